"""``toolpath smooth`` on a folder of other people's G-code, each output checked by a reader written apart.

Run: ``python -m toolpath.bench --only programs --programs DIR [--units mm]`` ->
``reports/bench/programs.json``.

Every ``.nc .ngc .tap .gcode .cnc`` file under DIR is smoothed in its own process at the default tolerance
(exit code and last line kept); a program that sets no units is run again with ``--units`` when it is
given, as a user told so would.  Each output that differs from its input is read back, with the input,
by :func:`feed_paths`: a minimal RS-274 reader that shares no code with :mod:`toolpath.gcode` (G0-G3,
I/J/K and R arcs in G17-G19, G20 / G21, G90 / G91, comments, N words, Fanuc program numbers, grbl's
``$`` reports and settings; a program holding anything else it
does not follow is counted as unchecked, never passed).  Per feed run, the two-sided distance of the
two paths, each sampled every :data:`STEP` mm (a KD-tree), so a figure may exceed the true one by
STEP / 2.  The JSON lists every program with its outcome; the summary counts them.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

SUFFIXES = {".nc", ".ngc", ".tap", ".gcode", ".cnc"}
STEP = 0.001  # mm between the samples of a path
_WORD = re.compile(r"([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")
_FOLLOWED_G = {0, 1, 2, 3, 4, 17, 18, 19, 20, 21, 40, 43, 49, 54, 55, 56, 57, 58, 59, 61, 64, 80, 90, 91, 94, 97}


class Unfollowed(ValueError):
    """The program holds a construct this minimal reader does not follow."""


def _arc(start, end, centre, clockwise: bool) -> list[tuple[float, float]]:
    """Points of a G17 arc from ``start`` to ``end`` about ``centre`` (a full circle when they meet), within
    STEP / 2 of it; the radius blends linearly from the start's to the end's, as a control's spiral does."""
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
    sweep = ((a0 - a1) if clockwise else (a1 - a0)) % (2 * math.pi) or 2 * math.pi
    r0, r1 = math.dist(start, centre), math.dist(end, centre)
    t = np.linspace(0.0, 1.0, max(2, math.ceil(sweep * max(r0, r1) / STEP)) + 1)[1:]
    angle = a0 + (-sweep if clockwise else sweep) * t
    radius = r0 + (r1 - r0) * t
    points = list(zip(centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle), strict=True))
    points[-1] = tuple(end)
    return points


# RS-274's arc planes: (first axis, second axis, their centre words); clockwise as seen from the third axis
_PLANES = {17: ("X", "Y", "I", "J"), 18: ("Z", "X", "K", "I"), 19: ("Y", "Z", "J", "K")}
_AXES = "XYZ"
_PROGRAM_NUMBER = re.compile(r"[oO]\s*\d+$")  # a Fanuc / Haas program number (run with --dialect fanuc)
_GRBL_MOVING = ("$H", "$J", "$RST")  # grbl system commands after which the position is the machine's


def _arc_points(start, end, words: dict, plane: int, clockwise: bool, scale: float) -> list:
    """XYZ points of an arc in ``plane`` (a helix along the third axis), by :func:`_arc` in the plane's axes."""
    a, b, i, j = _PLANES[plane]
    ia, ib = _AXES.index(a), _AXES.index(b)
    p0, p1 = (start[ia], start[ib]), (end[ia], end[ib])
    if "R" in words:
        r, chord = words["R"] * scale, math.dist(p0, p1)
        h = math.sqrt(max(r * r - chord * chord / 4.0, 0.0)) * (1 if (not clockwise) == (r > 0) else -1)
        mid = ((p0[0] + p1[0]) / 2.0, (p0[1] + p1[1]) / 2.0)
        centre = (mid[0] - h * (p1[1] - p0[1]) / chord, mid[1] + h * (p1[0] - p0[0]) / chord)
    else:
        centre = (p0[0] + words.get(i, 0.0) * scale, p0[1] + words.get(j, 0.0) * scale)
    planar = _arc(p0, p1, centre, clockwise)
    third = 3 - ia - ib
    along = np.linspace(start[third], end[third], len(planar) + 1)[1:]
    points = []
    for (u, v), w in zip(planar, along, strict=True):
        point = [0.0, 0.0, 0.0]
        point[ia], point[ib], point[third] = u, v, w
        points.append(tuple(point))
    return points


def feed_paths(text: str) -> list[np.ndarray]:
    """The XY polyline of every feed run (G1-G3 moves between rapids), in mm; arcs of the XZ / YZ planes
    are followed in 3-D and projected.  A Fanuc program number and grbl's ``$`` reports and settings are
    read past; grbl homing, jogging or an offset reset make the program unfollowed."""
    pos = [0.0, 0.0, 0.0]
    inch, absolute, motion, plane = False, True, None, 17
    runs: list[np.ndarray] = []
    current: list[tuple[float, float, float]] | None = None
    for raw in text.splitlines():
        line = re.sub(r"\([^)]*\)|;.*", " ", raw).strip().lstrip("/").strip()
        if not line or line.startswith("%") or _PROGRAM_NUMBER.match(line) or set(line) <= set("?~!"):
            continue
        if line.startswith("$"):
            if line.upper().startswith(_GRBL_MOVING):
                raise Unfollowed(f"grbl {line[:10]}")
            continue
        if any(c in line for c in "#[@^oO"):
            raise Unfollowed(f"parameters, expressions, polar words or O-words: {raw.strip()[:40]}")
        words = [(letter.upper(), float(value)) for letter, value in _WORD.findall(line)]
        if any(letter in "ABCUVWE" for letter, _ in words):
            raise Unfollowed(f"an axis beyond XYZ: {raw.strip()[:40]}")
        for code in (value for letter, value in words if letter == "G"):
            if code not in _FOLLOWED_G and not (code == 53 and not {"X", "Y"} & {w for w, _ in words}):
                raise Unfollowed(f"G{code:g}")  # (a G53 move of Z alone leaves the XY path as it is)
            motion = int(code) if code in (0, 1, 2, 3) else None if code == 80 else motion
            plane = int(code) if code in _PLANES else plane
            inch = code == 20 or (inch and code != 21)
            absolute = code == 90 or (absolute and code != 91)
        given = dict(words)
        scale = 25.4 if inch else 1.0
        explicit_arc = any(letter == "G" and value in (2, 3) for letter, value in words)
        if not (any(a in given for a in _AXES) or (explicit_arc and any(c in given for c in "IJK"))):
            if any(m in (2, 30) for letter, m in words if letter == "M"):
                break
            continue
        new = [(given[a] * scale if absolute else pos[k] + given[a] * scale) if a in given else pos[k]
               for k, a in enumerate(_AXES)]
        if motion in (1, 2, 3):
            current = current or [tuple(pos)]
            current += [tuple(new)] if motion == 1 else _arc_points(pos, new, given, plane, motion == 2, scale)
        elif current is not None:
            runs += [np.array(current)[:, :2]] if len(current) > 1 else []
            current = None
        pos = new
    if current is not None and len(current) > 1:
        runs.append(np.array(current)[:, :2])
    return runs


def _dense(path: np.ndarray) -> np.ndarray:
    steps = np.maximum(1, np.ceil(np.hypot(*np.diff(path, axis=0).T) / STEP).astype(int))
    parts = [path[:1]] + [a + (b - a) * (np.arange(1, k + 1) / k)[:, None]
                          for a, b, k in zip(path[:-1], path[1:], steps, strict=True)]
    return np.vstack(parts)


def two_sided(a: np.ndarray, b: np.ndarray) -> float:
    """The two-sided (Hausdorff) distance of two polylines, each sampled every STEP mm."""
    from scipy.spatial import cKDTree

    da, db = _dense(a), _dense(b)
    return float(max(cKDTree(db).query(da)[0].max(), cKDTree(da).query(db)[0].max()))


def _changed_distance(a: np.ndarray, b: np.ndarray) -> float:
    """:func:`two_sided` over the stretches where two runs of as many points differ, each with its unchanged
    neighbours (an upper bound of the whole runs' distance: the shared points are 0 apart, and a nearest
    point is sought in the stretch only); whole runs where the counts differ.  A 100 m contour sampled
    every micrometre would not fit in memory."""
    if len(a) != len(b):
        return two_sided(a, b)
    differs = np.flatnonzero(np.any(a != b, axis=1))
    breaks = np.flatnonzero(np.diff(differs) > 2) + 1
    return max(two_sided(a[max(k[0] - 1, 0):k[-1] + 2], b[max(k[0] - 1, 0):k[-1] + 2])
               for k in np.split(differs, breaks))


def check(source: str, output: str) -> dict:
    """The output's feed runs against the input's: count and largest two-sided distance (mm)."""
    try:
        before, after = feed_paths(source), feed_paths(output)
    except Unfollowed as exc:
        return {"checked": False, "why": str(exc)}
    if len(before) != len(after):
        return {"checked": True, "runs_match": False, "runs": [len(before), len(after)]}
    worst = max((_changed_distance(p, q) for p, q in zip(before, after, strict=True) if not np.array_equal(p, q)),
                default=0.0)
    return {"checked": True, "runs_match": True, "largest_distance_mm": worst}


def _smooth(path: Path, out: Path, extra: list[str]) -> tuple[int, str]:
    done = subprocess.run([sys.executable, "-m", "toolpath.cli", "smooth", str(path), "-o", str(out), "--force",
                           *extra], capture_output=True, text=True, timeout=600, check=False)
    said = [line for line in (done.stdout + done.stderr).splitlines() if line.strip()]
    # paths out of the recorded line, so two runs of the bench compare byte for byte
    last = said[-1].replace(str(out), "out.nc").replace(str(path.parent) + "/", "") if said else ""
    return done.returncode, last[:300]


def measure(folder: Path, units: str | None) -> dict:
    """Every program under ``folder``: exit code, last line, and the independent check of a changed output."""
    programs = sorted(p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() in SUFFIXES)
    rows: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out.nc"
        for path in programs:
            code, said = _smooth(path, out, [])
            row = {"exit": code, "said": said}
            for _ in range(2):  # what the tool asks a user for, given as a user told so would
                dialect = re.search(r"pass --dialect (\w+)", said) if code != 0 else None
                if code == 2 and units and "sets no units" in said and "units_given" not in row:
                    extra, row["units_given"] = ["--units", units], units
                elif dialect and "dialect_given" not in row:
                    extra, row["dialect_given"] = ["--dialect", dialect.group(1)], dialect.group(1)
                else:
                    break
                code, said = _smooth(path, out, [*row.get("extra", []), *extra])
                row.update({"exit": code, "said": said, "extra": [*row.get("extra", []), *extra]})
            row.pop("extra", None)
            if code == 0 and out.read_bytes() != path.read_bytes():  # latin-1: comments may be in any 8-bit code
                row["check"] = check(path.read_text(encoding="latin-1"), out.read_text(encoding="latin-1"))
            rows[str(path.relative_to(folder))] = row
    checked = [r["check"] for r in rows.values() if "check" in r and r["check"]["checked"]]
    return {"folder": str(folder), "step_mm": STEP, "programs": rows, "summary": {
        "programs": len(rows), "exit_0": sum(r["exit"] == 0 for r in rows.values()),
        "refused": sum(r["exit"] != 0 for r in rows.values()), "changed": sum("check" in r for r in rows.values()),
        "checked": len(checked), "runs_mismatch": sum(not c["runs_match"] for c in checked),
        "largest_distance_mm": max((c.get("largest_distance_mm", 0.0) for c in checked), default=0.0)}}
