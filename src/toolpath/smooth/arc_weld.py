"""``toolpath smooth --arcs``: runs of G1 lines replaced by one G2/G3 where an arc lies within the
tolerance of the original path, as ArcWelder does for 3-D printers (fewer, longer blocks: a controller
plans an arc at constant curvature instead of a chain of tiny corners).

Which lines.  A run of consecutive lines (nothing between them) that are each one plain G1 move in
the XY plane (:func:`toolpath.gcode.edit.movable_lines`), in absolute mode, with no block delete ``/``
and no comment (a line an arc replaces is gone, with all it holds), with an F word on the first line
at most.  The arc replaces lines ``L(i+1)..L(q)`` (points ``i..q``): the first becomes
``[N..] G2|G3 X Y I J [F..]`` with its line ending, the others are removed; the line after the arc,
always a G1 of the run, gets an explicit ``G1`` (after its N word) if it relied on the modal one.  Programs that use
G90.1 (absolute arc centres) are left alone.

The fit.  The arc passes through the run's first and last point exactly (its centre on their
perpendicular bisector, placed by least squares on the points between), turns one way by less than a
full circle, and is grown one point at a time while it stays within the budget.  The budget is the
tolerance less what writing it costs: half a unit of the last decimal on the end point and on I/J
(the reader blends the two radii) and the reader's chord tolerance.  While the arc grows it is held
to an O(n) upper bound of the two-sided distance (:func:`arc_bound`); :func:`weld_arcs` then re-reads
its output and measures every arc exactly (the Hausdorff distance of the polylines read back).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace

import numpy as np

from toolpath.gcode.edit import movable_lines, program_coordinates
from toolpath.gcode.errors import GCodeError
from toolpath.gcode.lexer import tokenize
from toolpath.gcode.reader import MM_PER_INCH, Program, ReaderOptions
from toolpath.gcode.reading import Reading
from toolpath.gcode.writer import fmt
from toolpath.geometry.hausdorff import hausdorff
from toolpath.labels.windows import feed_runs
from toolpath.smooth.rewrite import line_decimals, switch_stable

MIN_SEGMENTS = 3     # an arc replaces at least three G1 lines
LOOKAHEAD = 8        # growth tries this many longer arcs past the first that fails (the fit moves as it grows)
CHECK_CHORD = 1e-4   # mm: chords of the arcs the fit and the re-read check measure (within this of the arc)
MAX_SEGMENTS = 200   # growth stops here: fitting is quadratic in the arc's length
MAX_RADIUS = 10_000.0  # mm: flatter than this a G1 is as good, and I/J lose precision
_ABSOLUTE_CENTRES = re.compile(r"G\s*0*90\s*\.\s*1(?!\d)", re.IGNORECASE)
_LEADING_N = re.compile(r"[ \t]*(?:[Nn][ \t]*\d+[ \t]*)?")


@dataclass
class ArcRecord:
    """One arc written: the lines it replaced (of the input), its radius and its deviation."""

    first_line: int
    last_line: int
    lines_replaced: int
    radius_mm: float
    clockwise: bool
    deviation_mm: float


@dataclass(frozen=True)
class _Arc:
    centre: np.ndarray
    radius: float
    sweep: float  # signed, radians (negative: clockwise)


def fit_arc(points: np.ndarray, centre: np.ndarray | None = None) -> _Arc | None:
    """The circle through ``points[0]`` and ``points[-1]`` nearest (algebraically) to the points between
    (or the one about ``centre``, on their bisector), when the points turn one way about it by less than
    a full circle; None otherwise."""
    origin = points[0]
    p = points - origin  # local coordinates: no cancellation far from the machine origin
    chord = p[-1]
    length = float(np.hypot(*chord))
    if length == 0.0 or len(p) < 3:
        return None
    mid, normal = chord / 2.0, np.array([-chord[1], chord[0]]) / length
    inner = p[1:-1]
    # |q - c|^2 = |c|^2 (through the start, at 0) is linear in c: 2 q.c = |q|^2; with c = mid + t normal
    a = 2.0 * inner @ normal
    b = np.einsum("ij,ij->i", inner, inner) - 2.0 * inner @ mid
    if float(a @ a) < 1e-18:
        return None  # the points lie on the chord: a straight line
    centre = mid + normal * float(a @ b) / float(a @ a) if centre is None else np.asarray(centre) - origin
    radius = float(np.hypot(*centre))
    if not math.isfinite(radius) or radius > MAX_RADIUS:
        return None
    angles = np.unwrap(np.arctan2(p[:, 1] - centre[1], p[:, 0] - centre[0]))
    steps = np.diff(angles)
    if not (np.all(steps > 0) or np.all(steps < 0)) or np.abs(steps).max() >= math.pi / 2:
        return None
    sweep = float(angles[-1] - angles[0])
    if abs(sweep) >= 2.0 * math.pi - 1e-9:
        return None
    return _Arc(centre + origin, radius, sweep)


def arc_bound(original: np.ndarray, arc: _Arc) -> float:
    """An upper bound, in O(n), of the two-sided distance between the original polyline and the arc:
    the vertices' largest distance off the circle plus the largest sagitta of a segment on it.  It
    holds when the vertices turn one way about the centre (inf otherwise): then every point of a
    segment lies within its ends' radial error plus its sagitta of the arc, and every point of the
    arc within that of the segment whose vertices bracket its angle."""
    offset = original - arc.centre
    angles = np.unwrap(np.arctan2(offset[:, 1], offset[:, 0]))
    steps = np.diff(angles)
    if not (np.all(steps * np.sign(arc.sweep) > 0)) or np.abs(steps).max() >= math.pi / 2:
        return math.inf
    radial = float(np.abs(np.hypot(offset[:, 0], offset[:, 1]) - arc.radius).max())
    half = np.hypot(*np.diff(original, axis=0).T) / 2.0
    sagitta = float((arc.radius - np.sqrt(np.maximum(arc.radius ** 2 - half ** 2, 0.0))).max())
    return radial + sagitta


def _bare(raw: str) -> bool:
    """No block delete and no comment: a line an arc may replace without dropping what a controller reads
    (a ``/`` line runs or not by the switch; a comment may be a MSG or DEBUG the operator sees)."""
    return not any(c in raw for c in "/(;")


def _chains(program: Program, stable: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray, int, int]]:
    """Per feed run, maximal point ranges ``i..e`` whose lines ``L(i+1)..L(e)`` are consecutive plain G1
    lines in absolute mode, with no block delete or comment, an F word only on the first, none read past
    blind (:mod:`toolpath.gcode.passing`), and (``stable``) where the tool stands after ``L(i)..L(e)`` the
    same with the block-delete switch on or off:
    (xy, lines, i, e)."""
    movable = movable_lines(program) & np.array([_bare(raw) for raw in program.lines], bool)
    stable = np.ones(len(program.lines) + 1, bool) if stable is None else stable
    stable = stable & ~program.states.blind  # where the reader read past a construct: never welded
    out = []
    for xy, lines in feed_runs(program):
        ok = np.zeros(len(lines), bool)
        for k in range(1, len(lines)):
            line = int(lines[k])
            ok[k] = bool(movable[line - 1]) and line == int(lines[k - 1]) + 1 and program.states[line].absolute \
                and bool(stable[line]) and bool(stable[int(lines[k - 1])])
        k = 1
        while k < len(lines):
            if not ok[k]:
                k += 1
                continue
            i = k - 1
            while k < len(lines) and ok[k] and (k == i + 1 or not _has_feed(program, int(lines[k]))):
                k += 1
            out.append((xy, lines, i, k - 1))
    return out


def _has_feed(program: Program, line: int) -> bool:
    return any(w.letter == "F" for w in tokenize(program.lines[line - 1].rstrip("\r\n"), program.source,
                                                 line).words)


def weld_arcs(current: Program, original: Program, tolerance: float, read_options: ReaderOptions | None = None,
              start: Reading | None = None) -> tuple[str, list[ArcRecord], list[int], str | None]:
    """The text of ``current`` (the smoothed program, its lines those of ``original``) with G1 runs
    replaced by arcs within ``tolerance`` of ``original``'s path; the arcs; the input lines changed or
    removed; why no arc was tried (or None); how many arcs the exact check rejected and were kept as
    their G1 lines.  ``start``: for a part of a program, the reading its output is re-read from.

    Raises
    ------
    GCodeError
        When the re-read output moved a point outside the arcs (an internal error: nothing should be written).
    """
    if _ABSOLUTE_CENTRES.search("".join(current.lines)):
        return "".join(current.lines), [], [], "the program uses G90.1 (absolute arc centres): arcs are not fitted", 0
    # the re-read check reads the arcs as chords within CHECK_CHORD of them (whatever the caller's tolerance)
    read_options = replace(read_options or (start.options if start is not None else ReaderOptions()),
                           chord_tolerance=CHECK_CHORD)
    start = start.with_options(read_options) if start is not None else None
    point_of_line = {int(line): k for k, line in enumerate(original.lines_of_points)}
    edits: dict[int, str] = {}
    records: list[ArcRecord] = []
    written: dict[int, tuple] = {}  # per arc, what wrote it
    kept_as_lines = 0
    for xy, lines, first, last in _chains(current, switch_stable(current, read_options, start)):
        original_xy = np.array([original.points[point_of_line[int(line)], :2] for line in lines[first:last + 1]])
        i = first
        while i + MIN_SEGMENTS <= last - 1:  # the chain's last line stays a G1 after the arcs
            best, misses = None, 0
            for q in range(i + MIN_SEGMENTS, min(last - 1, i + MAX_SEGMENTS) + 1):
                found = _try(current, xy, lines, original_xy[i - first:q - first + 1], i, q, tolerance)
                if found is None:
                    misses += 1
                    if misses > LOOKAHEAD:
                        break
                    continue
                best, misses = (q, *found), 0
            if best is None:
                i += 1
                continue
            q, arc, deviation = best
            record = ArcRecord(int(lines[i + 1]), int(lines[q]), q - i, arc.radius, arc.sweep < 0, deviation)
            written[id(record)] = (xy, lines, i, q, arc)
            _write(current, xy, lines, i, q, arc, edits)
            records.append(record)
            i = q
    text = "".join(edits.get(n, raw) for n, raw in enumerate(current.lines, start=1))
    while records and (failed := _verify(text, current, original, records, tolerance, read_options, start)):
        # an arc the exact check rejects is kept as its G1 lines: the others are written again without it
        # (the line after an arc may be the next arc's first) and checked again
        records = [r for r in records if r not in failed]
        kept_as_lines += len(failed)
        edits = {}
        for record in records:
            _write(current, *written[id(record)], edits)
        text = "".join(edits.get(n, raw) for n, raw in enumerate(current.lines, start=1))
    return text, records, sorted(edits), None, kept_as_lines


def _try(program: Program, xy, lines, original_xy, i: int, q: int, tolerance: float):
    arc = fit_arc(xy[i:q + 1])
    if arc is None:
        return None
    found = _within(program, lines, original_xy, q, tolerance, arc)
    if found is None and (closer := minimax_arc(xy[i:q + 1], arc)) is not None:
        found = _within(program, lines, original_xy, q, tolerance, closer)
    return found


def minimax_arc(points: np.ndarray, arc: _Arc) -> _Arc | None:
    """The arc through the same two end points whose largest radial miss of the points between is least
    (a grid over the centre's place on the chord's bisector around ``arc``'s): the least-squares centre
    spends the band evenly, this one spends it where the points need it."""
    origin, chord = points[0], points[-1] - points[0]
    length = float(np.hypot(*chord))
    mid, normal = chord / 2.0, np.array([-chord[1], chord[0]]) / length
    t0 = float((arc.centre - origin - mid) @ normal)
    t = t0 + np.linspace(-1.0, 1.0, 161)[:, None] * 0.05 * (abs(t0) + length)  # (T, 1)
    centres = mid + t * normal  # (T, 2), local coordinates
    inner = points[1:-1] - origin
    radii = np.hypot(centres[:, 0], centres[:, 1])
    miss = np.abs(np.hypot(inner[None, :, 0] - centres[:, None, 0], inner[None, :, 1] - centres[:, None, 1])
                  - radii[:, None]).max(axis=1)
    best = int(np.argmin(miss))
    return fit_arc(points, centre=centres[best] + origin)


def _within(program: Program, lines, original_xy, q: int, tolerance: float, arc: _Arc):
    line = int(lines[q])
    scale = MM_PER_INCH if program.states[line].inch else 1.0
    rounding = 0.5 * 10.0 ** -line_decimals(program, line) * scale * math.sqrt(2.0)
    # the written arc moves by the end point's and I/J's rounding; the check reads it as chords
    budget = tolerance - 2.0 * rounding - 2.0 * CHECK_CHORD
    if budget <= 0:
        return None
    bound = ray_bound(original_xy, arc)  # O(n); the exact figure comes from the re-read check
    return (arc, bound) if bound <= budget else None


def ray_bound(original: np.ndarray, arc: _Arc) -> float:
    """An upper bound, in O(n), of the two-sided (Frechet, hence Hausdorff) distance between the original
    polyline and the arc, tighter than :func:`arc_bound`: when the vertices turn one way about the centre
    (inf otherwise), pair every point of the polyline with the arc's point on the same ray from the centre.
    Along a segment the distance to the centre is convex, so the largest ``|R - rho|`` of a segment is at
    an end or at its nearest point to the centre: ``max(|d_a - R|, |d_b - R|, R - d_min)``."""
    offset = original - arc.centre
    angles = np.unwrap(np.arctan2(offset[:, 1], offset[:, 0]))
    steps = np.diff(angles)
    if not (np.all(steps * np.sign(arc.sweep) > 0)) or np.abs(steps).max() >= math.pi / 2:
        return math.inf
    d = np.hypot(offset[:, 0], offset[:, 1])
    a, u = offset[:-1], np.diff(offset, axis=0)
    t = np.clip(-np.einsum("ij,ij->i", a, u) / np.maximum(np.einsum("ij,ij->i", u, u), 1e-300), 0.0, 1.0)
    nearest = np.hypot(a[:, 0] + t * u[:, 0], a[:, 1] + t * u[:, 1])
    return float(max(np.abs(d - arc.radius).max(), (arc.radius - nearest).max()))


def _write(program: Program, xy, lines, i: int, q: int, arc: _Arc, edits: dict[int, str]) -> None:
    """Write the arc over lines ``L(i+1)..L(q)`` into ``edits``."""
    first, end = int(lines[i + 1]), int(lines[q])
    raw = program.lines[first - 1]
    body = raw.rstrip("\r\n")
    words = tokenize(body, program.source, first).words
    decimals = line_decimals(program, end)
    state = program.states[first - 1]
    scale = MM_PER_INCH if state.inch else 1.0
    target = program_coordinates(program, end, xy[q])
    centre = (arc.centre - xy[i]) / scale
    parts = [f"N{w.text}" for w in words if w.letter == "N"]
    parts += [f"G{2 if arc.sweep < 0 else 3}", f"X{fmt(target[0], decimals)}", f"Y{fmt(target[1], decimals)}",
              f"I{fmt(centre[0], decimals)}", f"J{fmt(centre[1], decimals)}"]
    parts += [f"F{w.text}" for w in words if w.letter == "F"]
    edits[first] = " ".join(parts) + raw[len(body):]
    for line in range(first + 1, end + 1):
        edits[line] = ""
    after = end + 1  # a G1 of the chain: it must not inherit the arc's motion mode
    following = program.lines[after - 1]
    if not any(w.letter == "G" for w in tokenize(following.rstrip("\r\n"), program.source, after).words):
        # after a leading N word, where a controller expects it (LinuxCNC refuses an N in mid-line)
        number = _LEADING_N.match(following)
        edits.setdefault(after, following[:number.end()] + "G1 " + following[number.end():])


def _verify(text: str, current: Program, original: Program, records: list[ArcRecord], tolerance: float,
            read_options: ReaderOptions | None, start: Reading | None) -> list[ArcRecord]:
    """Re-read the output: every point outside the arcs is where it was (else GCodeError); the arcs that
    lie farther than the tolerance from the original (each record gets its exact deviation)."""
    final = (start.snapshot() if start is not None else Reading(current.source, read_options)).read(text)
    replaced = np.zeros(len(current.lines) + 1, bool)  # index = input line
    removed = np.zeros(len(current.lines) + 1, bool)
    for r in records:
        replaced[r.first_line:r.last_line + 1] = True
        removed[r.first_line + 1:r.last_line + 1] = True
    shift = np.cumsum(removed)  # an output line number is the input's less the lines removed before it
    arc_lines = np.array([r.first_line - shift[r.first_line] for r in records])
    kept_current = ~replaced[current.lines_of_points]
    kept_final = ~np.isin(final.lines_of_points, arc_lines)
    if not np.array_equal(current.points[kept_current], final.points[kept_final]):
        raise GCodeError(current.source, 0, "internal check failed: welding arcs moved a point it does not own")
    first_point = {int(line): k for k, line in enumerate(original.lines_of_points)}
    for r, line in zip(records, arc_lines, strict=True):
        a, b = first_point[r.first_line] - 1, first_point[r.last_line]  # the arc's start point and its end
        new = np.vstack([current.points[a, :2], final.points[final.lines_of_points == line, :2]])
        # the chords lie within CHECK_CHORD of the arc the controller runs: the bound of its distance
        r.deviation_mm = float(hausdorff(original.points[a:b + 1, :2], new)) + CHECK_CHORD
    return [r for r in records if r.deviation_mm > tolerance + 1e-9]
