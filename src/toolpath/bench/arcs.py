"""``toolpath smooth --arcs --method none`` beside ArcWelder (FormerLurker/ArcWelderLib) at one tolerance.

Run: ``python -m toolpath.bench --only arcs [--arcwelder PATH]`` (part of ``make bench``) ->
``reports/bench/arcs.json``.

ArcWelder is not a dependency: give its console binary with ``--arcwelder`` or ``$ARCWELDER``, or a
checkout of its source with ``$ARCWELDER_SRC`` (it is built here with CMake, :func:`build_arcwelder`);
without one, only our figures are written, and the JSON says why.  Both run in their own process,
one after another in one benchmark run, on every program of the shared corpus and on a G01-dense
program (:func:`toolpath.bench.gcode.write_dense`), at the same tolerance: ArcWelder's ``-r`` is a
resolution, twice the deviation it allows (``-r=0.02`` for 0.01 mm; in inches for a G20 program, whose
numbers ArcWelder takes for mm), with ``-y -d`` (arcs in XY only, no extrusion).
ArcWelder welds only lines that say ``G1`` and reads no ``#`` parameter, so it gets an
explicit copy of each program (:func:`explicit_copy`: the motion mode written on every move, ``G01`` as
``G1``, parameters replaced by the numbers our reader gives); its lines out are counted in its output,
header included.  Per program: lines out, arcs, the largest two-sided distance of the output's path to
the input's (both read with chords within :data:`CHORD` of the arcs, the figure less that chord, each
feed run measured exactly by :func:`toolpath.geometry.hausdorff.pieced_hausdorff`), seconds and peak
memory (``/usr/bin/time``'s maximum resident set: the small ``time`` process is the one forked).
The issue's speed and memory target is timed apart on a 1,000,000-line program of the same kind
(:func:`_large_run`: lines per second end to end and peak memory, both tools, no deviation measured).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from toolpath.gcode import ReaderOptions, read_text
from toolpath.gcode.reader import MM_PER_INCH
from toolpath.geometry.hausdorff import pieced_hausdorff
from toolpath.geometry.labels.windows import feed_runs

TOLERANCE = 0.01  # mm: the setting for both tools
CHORD = 1e-5      # mm: arcs read back as chords this close to them, for the deviation
CORPUS = Path(__file__).resolve().parents[3].parent / "shared" / "gcode-corpus"
DENSE_LINES = 20_000  # the G01-dense program measured for its deviation too (exact, per run: slow on long runs)
LARGE_LINES = 1_000_000  # the speed and memory target: timed only
_TIME = "/usr/bin/time"


def build_arcwelder(source: Path, build: Path) -> Path:
    """ArcWelder's console program built from a checkout of FormerLurker/ArcWelderLib (CMake, Release)."""
    build.mkdir(parents=True, exist_ok=True)
    subprocess.run(["cmake", str(source), "-DCMAKE_BUILD_TYPE=Release"], cwd=build, check=True,
                   capture_output=True)
    subprocess.run(["make", "-j2", "ArcWelderConsole"], cwd=build, check=True, capture_output=True)
    return build / "ArcWelderConsole" / "ArcWelder"


def find_arcwelder(given: str | None) -> tuple[Path | None, str]:
    """The binary and where it came from, or None and why not."""
    for candidate in (given, os.environ.get("ARCWELDER"), shutil.which("ArcWelder")):
        if candidate and Path(candidate).is_file():
            return Path(candidate), f"binary {candidate}"
    if source := os.environ.get("ARCWELDER_SRC"):
        try:
            return build_arcwelder(Path(source), Path(".cache/arcwelder-build")), f"built from {source}"
        except (OSError, subprocess.CalledProcessError) as error:
            return None, f"building ArcWelder from {source} failed: {error}"
    return None, "ArcWelder not given (--arcwelder PATH, $ARCWELDER or $ARCWELDER_SRC)"


_MOTION_WORD = re.compile(r"\bG0*([0-3])(?![\d.])", re.IGNORECASE)
_AXIS_WORD = re.compile(r"[XYZIJ]\s*[-+.\d#\[]", re.IGNORECASE)


def explicit_copy(text: str) -> str:
    """The program as ArcWelder can read it: every move states its motion mode (``G1``, not ``G01`` or a
    modal line), and a line with a ``#`` parameter or an expression is written with the numbers our reader
    gives it (an assignment becomes a comment).  The path is the same; only the spelling changes."""
    program = read_text(text)
    out = []
    for number, line in enumerate(text.splitlines(), start=1):
        code = re.sub(r"\(.*?\)|;.*", "", line)
        state = program.states[number]
        if re.match(r"\s*#", code):
            out.append(f"({line.strip()})")
        elif "#" in code or "[" in code:
            scale = MM_PER_INCH if state.inch else 1.0
            x, y, z = ((p - o) / scale for p, o in zip(state.position, state.offset, strict=True))
            # plain I / J / R words as written (an arc's centre), the position and feed as the reader has them
            centre = " ".join(w for w in re.findall(r"[IJR]\s*[-+]?[\d.]+", code, re.IGNORECASE))
            feed = f" F{state.feed / scale:g}" if re.search(r"F\s*[#\[]", code, re.IGNORECASE) else ""
            out.append(f"G{state.motion} X{x:.6f} Y{y:.6f} Z{z:.6f} {centre}".rstrip() + feed)
        elif _AXIS_WORD.search(code) and not _MOTION_WORD.search(code) and state.motion in (0, 1, 2, 3):
            out.append(f"G{state.motion} " + line.lstrip())
        else:
            out.append(_MOTION_WORD.sub(lambda m: f"G{m.group(1)}", line))
    return "\n".join(out) + "\n"


def deviation(before: str, after: str) -> float | str:
    """The largest two-sided distance (mm) between the paths of two programs, run by run, or why not."""
    fine = ReaderOptions(chord_tolerance=CHORD)
    try:
        a, b = feed_runs(read_text(before, options=fine)), feed_runs(read_text(after, options=fine))
    except Exception as error:  # noqa: BLE001 - a program our reader refuses is a result, not a crash
        return f"unreadable: {str(error)[:200]}"
    if len(a) != len(b):
        return f"feed runs differ: {len(a)} in, {len(b)} out"
    try:
        return max((_run_distance(p[0], q[0]) for p, q in zip(a, b, strict=True)), default=CHORD) - CHORD
    except MemoryError:  # a path that crosses itself often: the exact pieced measure needs more than this machine
        return "not measured: the exact distance needs more memory than this machine has (a self-crossing path)"


def _run_distance(before, after) -> float:
    # a run both tools left as it was (arcs the input already had) reads back point for point
    if before.shape == after.shape and (before == after).all():
        return CHORD
    return pieced_hausdorff(before, after)


def _timed(command: list[str]) -> dict:
    """Seconds (wall) and peak resident memory of one run of ``command``."""
    wrap = [_TIME, "-f", "%M"] if Path(_TIME).is_file() else []
    start = time.perf_counter()
    done = subprocess.run(wrap + command, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    result: dict = {"seconds": seconds, "exit": done.returncode}
    if wrap and done.stderr.strip():
        result["peak_rss_mb"] = int(done.stderr.strip().splitlines()[-1]) / 1024
    if done.returncode != 0:
        result["error"] = "\n".join(done.stderr.strip().splitlines()[-3:-1] if wrap else
                                    done.stderr.strip().splitlines()[-2:])[:300]
    return result


def _count(path: Path) -> dict:
    text = path.read_text(errors="replace")
    return {"lines_out": len(text.splitlines()),
            "arcs": len(re.findall(r"^\s*(?:N\d+\s*)?G0*[23](?![\d.])", text, re.IGNORECASE | re.MULTILINE))}


def run_ours(source: Path, folder: Path) -> dict:
    out = folder / f"{source.stem}.ours.nc"
    command = [sys.executable, "-m", "toolpath.cli", "smooth", str(source), "-o", str(out), "--force",
               "--method", "none", "--arcs", "--tolerance", str(TOLERANCE)]
    result = _timed(command)
    if result["exit"] != 0 and "sets no units" in result.get("error", ""):
        result = _timed(command + ["--units", "mm"]) | {"units": "--units mm (the program sets none)"}
    if result["exit"] == 0:
        result |= _count(out)
        result["deviation_mm"] = deviation(source.read_text(errors="replace"), out.read_text())
    return result


def run_arcwelder(binary: Path, source: Path, folder: Path) -> dict:
    explicit = folder / f"{source.stem}.explicit.nc"
    explicit.write_text(explicit_copy(source.read_text(errors="replace")))
    copy_deviation = deviation(source.read_text(errors="replace"), explicit.read_text())  # the copy is the same path
    out = folder / f"{source.stem}.arcwelder.nc"
    # ArcWelder reads every number as mm: an inch program (G20) gets the same tolerance in inches
    states = read_text(explicit.read_text()).states
    inch = any(states[n].inch for n in range(1, len(states)))
    resolution = 2 * TOLERANCE / (MM_PER_INCH if inch else 1.0)
    result = _timed([str(binary), f"-r={resolution:.6g}", "-y", "-d", "-p=NONE", "-l=ERROR", str(explicit), str(out)])
    result["resolution"] = f"-r={resolution:.6g}" + (" (G20: 0.02 mm in inches)" if inch else "")
    if result["exit"] == 0:
        result |= _count(out)
        result["deviation_mm"] = deviation(explicit.read_text(), out.read_text(errors="replace"))
    return result | {"explicit_copy_deviation_mm": copy_deviation}


def _large_run(folder: Path, lines: int, seed: int, binary: Path | None) -> dict:
    """The issue's speed and memory target: ``--arcs --method none`` on a ``lines``-line G01-dense program,
    end to end in its own process (our own exact re-read check included; no deviation measured here, the
    20,000-line row above has it), ArcWelder on the same program beside it."""
    from toolpath.bench.gcode import write_dense

    path = folder / "large.nc"
    write_dense(path, lines, seed, spikes=0.0)
    out = folder / "large.ours.nc"
    ours = _timed([sys.executable, "-m", "toolpath.cli", "smooth", str(path), "-o", str(out), "--force",
                   "--method", "none", "--arcs", "--tolerance", str(TOLERANCE)])
    if ours["exit"] == 0:
        ours |= _count(out) | {"lines_per_s": lines / ours["seconds"]}
        out.unlink()
    result = {"lines_in": lines, "seed": seed, "ours": ours}
    if binary is not None:
        theirs = _timed([str(binary), f"-r={2 * TOLERANCE:.6g}", "-y", "-d", "-p=NONE", "-l=ERROR", str(path),
                         str(folder / "large.arcwelder.nc")])
        if theirs["exit"] == 0:
            theirs |= _count(folder / "large.arcwelder.nc") | {"lines_per_s": lines / theirs["seconds"]}
        result["arcwelder"] = theirs
    return result


def measure(arcwelder: str | None = None, corpus: Path = CORPUS, dense_lines: int = DENSE_LINES,
            seed: int = 0, large_lines: int = LARGE_LINES) -> dict:
    from toolpath.bench.gcode import write_dense

    binary, origin = find_arcwelder(arcwelder)
    programs = sorted(p for p in corpus.glob("*") if p.suffix.lower() in {".ngc", ".nc", ".gcode", ".tap"}) \
        if corpus.is_dir() else []
    rows = {}
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        dense = folder / "dense.nc"
        write_dense(dense, dense_lines, seed, spikes=0.0)
        for path in [*programs, dense]:
            row = {"lines_in": len(path.read_text(errors="replace").splitlines()), "ours": run_ours(path, folder)}
            if binary is not None:
                row["arcwelder"] = run_arcwelder(binary, path, folder)
            rows[path.name if path != dense else f"G01-dense ({dense_lines:,} lines, seed {seed})"] = row
        large = _large_run(folder, large_lines, seed, binary) if large_lines else None
    dense_row = rows[next(reversed(rows))]
    return {"tolerance_mm": TOLERANCE, "chord_mm": CHORD, "arcwelder": origin,
            "arcwelder_flags": f"-r={2 * TOLERANCE} -y -d (on the explicit copy)",
            "corpus": str(corpus) if programs else f"{corpus} absent", "programs": rows,
            "arcs_only_lines_per_s": dense_row["lines_in"] / dense_row["ours"]["seconds"],
            "large_program": large,
            "targets": {"cat_outline_lines_out": 512, "deviation_mm": TOLERANCE,
                        "arcs_only_lines_per_s_1M": 200_000, "peak_rss_mb_1M": 300}}
