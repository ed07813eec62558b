"""``toolpath smooth --arcs``: runs of G1 lines replaced by one G2/G3 where an arc lies within the
tolerance of the original path, as ArcWelder does for 3-D printers (fewer, longer blocks: a controller
plans an arc at constant curvature instead of a chain of tiny corners).

Which lines.  A run of consecutive lines (nothing between them) that are each one plain G1 move in the XY
plane (:func:`toolpath.gcode.edit.movable_lines`), in absolute mode, with no block delete ``/`` and no comment
(a line an arc replaces is gone, with all it holds), with an F word on the first line at most (or one that
repeats the feed in effect, outside inverse time G93: a controller does nothing with it).  The arc replaces
lines ``L(i+1)..L(q)`` (points ``i..q``): the first becomes ``[N..] G2|G3 X Y I J [F..]`` with its line
ending, the others are removed; the line after the arc, always a G1 of the run, gets an explicit ``G1`` (after
its N word) if it relied on the modal one.  Programs that use G90.1 (absolute arc centres) are left alone.

The fit.  Each arc passes through its first and last point (its centre on their perpendicular
bisector), turns one way by less than a full circle, and lies within the budget: the tolerance less the
reader's chord tolerance, measured on the arc as it is written (end point and I/J rounded to the line's
decimals, the reader's spiral between the two radii) by an upper bound of the two-sided distance
(:func:`spiral_bound`).  Which arcs: every start and end screened at once, then the breaks that leave
the fewest lines by dynamic programming (:mod:`toolpath.smooth.arc_search`); each chosen arc is measured
again with its numbers as formatted, and :func:`weld_arcs` re-reads its output and measures every arc
exactly (the Hausdorff distance of the polylines read back); an arc that fails is kept as its lines.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace

import numpy as np

from toolpath.gcode.edit import program_coordinates
from toolpath.gcode.errors import GCodeError
from toolpath.gcode.lexer import tokenize
from toolpath.gcode.reader import MM_PER_INCH, Motion, Program, ReaderOptions
from toolpath.gcode.reading import Reading
from toolpath.gcode.writer import fmt
from toolpath.geometry.hausdorff import pieced_hausdorff
from toolpath.smooth.arc_runs import edited, last_point_of, occurs, sets_motion, text_of, weldable_runs
from toolpath.smooth.arc_search import Chain, fewest_blocks
from toolpath.smooth.rewrite import decimals_of, line_decimals, switch_stable

MIN_SEGMENTS = 2     # an arc replaces at least three G1 lines
LOOKAHEAD = 8        # a start is measured further while an arc fits within this many ends of its block's edge
CHECK_CHORD = 2e-5   # mm: chords of the arcs the fit and the re-read check measure (within this of the arc)
MAX_SEGMENTS = 2000  # growth stops here: on a 20,000-line dense program 800 wrote 31 lines (16 s), 2,000 wrote
#                     16 (38 s), 5,000 wrote 10 (103 s); ArcWelder wrote 29 (12 of them its header)
COMPILED_POINTS = 2_000  # chain points from which the screen and the check run in compiled loops (numba)
MAX_RADIUS = 10_000.0  # mm: flatter than this a G1 is as good, and I/J lose precision
_ABSOLUTE_CENTRES = re.compile(r"G[^\S\r\n]*0*90[^\S\r\n]*\.[^\S\r\n]*1(?!\d)", re.IGNORECASE)  # within a line
_LEADING_N = re.compile(r"[^\S\r\n]*(?:[Nn][^\S\r\n]*\d+[^\S\r\n]*)?")


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
    if centre is not None:
        centre = np.asarray(centre) - origin
    elif float(a @ a) < 1e-18:
        return None  # the points lie on the chord: a straight line
    else:
        centre = mid + normal * float(a @ b) / float(a @ a)
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


def weld_arcs(current: Program, original: Program, tolerance: float, read_options: ReaderOptions | None = None,
              start: Reading | None = None) -> tuple[str, list[ArcRecord], np.ndarray, str | None, int]:
    """The text of ``current`` (the smoothed program as read from its text, its lines those of ``original``:
    the check compares its points with the output's as read) with G1 runs
    replaced by arcs within ``tolerance`` of ``original``'s path; the arcs; the input lines changed or
    removed (ascending); why no arc was tried (or None); how many arcs the exact check rejected and were kept as
    their G1 lines.  ``start``: for a part of a program, the reading its output is re-read from.

    Raises
    ------
    GCodeError
        When the re-read output moved a point outside the arcs (an internal error: nothing should be written).
    """
    if occurs(current, _ABSOLUTE_CENTRES):
        return (text_of(current), [], np.zeros(0, np.int64),
                "the program uses G90.1 (absolute arc centres): arcs are not fitted", 0)
    # the re-read check reads the arcs as chords within CHECK_CHORD of them (whatever the caller's tolerance)
    read_options = replace(read_options or (start.options if start is not None else ReaderOptions()),
                           chord_tolerance=CHECK_CHORD)
    start = start.with_options(read_options) if start is not None else None
    edits: dict[int, str] = {}  # lines rewritten (an arc's first, the line after it)
    removed: list[tuple[int, int]] = []  # lines an arc replaces after its first, as (first, last)
    records: list[ArcRecord] = []
    written: dict[int, tuple] = {}  # per arc, what wrote it
    kept_as_lines = 0
    chains = weldable_runs(current, switch_stable(current, read_options, start))
    # numba's import (about 0.5 s, where the fast extra is installed) pays for itself from a few thousand points
    compiled = sum(last - first + 1 for _, _, first, last, _ in chains) >= COMPILED_POINTS
    for xy, lines, first, last, open_end in chains:
        original_xy = original.points[last_point_of(original, lines[first:last + 1]), :2]
        chosen, rejected = _fewest_lines(current, xy, lines, original_xy, first, last, open_end, tolerance,
                                         compiled)
        kept_as_lines += rejected  # the screen chose them, their own measure as written did not
        for i, q, arc, deviation in chosen:
            record = ArcRecord(int(lines[i + 1]), int(lines[q]), q - i, arc.radius, arc.sweep < 0, deviation)
            written[id(record)] = (xy, lines, i, q, arc)
            _write(current, xy, lines, i, q, arc, edits, removed)
            records.append(record)
    text = edited(current, edits, removed)
    while records and (failed := _verify(text, current, original, records, tolerance, read_options, start,
                                         compiled)):
        # an arc the exact check rejects is kept as its G1 lines: the others are written again without it
        # (the line after an arc may be the next arc's first) and checked again
        records = [r for r in records if r not in failed]
        kept_as_lines += len(failed)
        edits, removed = {}, []
        for record in records:
            _write(current, *written[id(record)], edits, removed)
        text = edited(current, edits, removed)
    changed = np.concatenate([np.fromiter(edits, np.int64, len(edits))]
                             + [np.arange(a, b + 1, dtype=np.int64) for a, b in removed])
    changed.sort()  # unique by neighbours: np.unique hashes a million lines several times slower
    return text, records, changed[np.r_[True, changed[1:] != changed[:-1]][:len(changed)]], None, kept_as_lines


def _fewest_lines(program: Program, xy, lines, original_xy, first: int, last: int, open_end: bool,
                  tolerance: float, compiled: bool = False):
    """The arcs over points ``first..last`` of a chain that leave the fewest lines
    (:func:`toolpath.smooth.arc_search.fewest_blocks`), each measured again as it is written.  The
    chain's last line stays a G1 unless ``open_end`` (the line after an arc must set its own motion mode,
    or be one the tool may write ``G1`` on).  Also how many arcs the screen chose that their own measure
    rejected (kept as their lines)."""
    span = lines[first:last + 1].astype(np.int64)
    inch = program.states.inch[span - 1].astype(bool)
    before = np.append(span[1:] - 1, span[-1])  # an arc from point k is written on line L(k+1)
    chain = Chain(xy[first:last + 1], original_xy, program_coordinates(program, span, xy[first:last + 1]),
                  np.where(inch, MM_PER_INCH, 1.0), decimals_of(program, span),
                  np.where(program.states.inch[before - 1].astype(bool), MM_PER_INCH, 1.0), compiled)
    end = (last if open_end else last - 1) - first
    chosen, rejected = [], 0
    for i, q, centre in fewest_blocks(chain, end, tolerance - 2.0 * CHECK_CHORD, MIN_SEGMENTS, MAX_SEGMENTS,
                                      MAX_RADIUS, LOOKAHEAD):
        # an end the search took to fit without measuring it has no centre: the arc is fitted afresh
        arc = fit_arc(xy[first + i:first + q + 1], centre=centre if np.all(np.isfinite(centre)) else None)
        found = None if arc is None else _within(program, xy, lines, original_xy[i:q + 1], first + i, first + q,
                                                 tolerance, arc)
        if found is not None:  # the screen rounds as NumPy does; the line is written as Python formats
            chosen.append((first + i, first + q, *found))
        else:
            rejected += 1
    return chosen, rejected


def _within(program: Program, xy, lines, original_xy, i: int, q: int, tolerance: float, arc: _Arc):
    # measured on the arc as written (end point and I/J rounded) and read back (a spiral between the two
    # radii); the re-read check reads it as chords within CHECK_CHORD and adds that to what it measures
    budget = tolerance - 2.0 * CHECK_CHORD
    _, end, centre = _as_written(program, xy, lines, i, q, arc)
    bound = spiral_bound(original_xy, xy[i], end, centre, arc.sweep < 0)  # O(n); exact figure: the re-read check
    return (arc, bound) if bound <= budget else None


def _as_written(program: Program, xy, lines, i: int, q: int, arc: _Arc) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The numbers :func:`_write` writes for the arc over ``L(i+1)..L(q)`` (X, Y, I, J), and the end
    point and centre (mm) a reader takes from them."""
    first, end = int(lines[i + 1]), int(lines[q])
    decimals = line_decimals(program, end)
    scale = MM_PER_INCH if program.states[first - 1].inch else 1.0
    target = program_coordinates(program, end, xy[q])
    texts = [fmt(float(v), decimals) for v in (*target, *((arc.centre - xy[i]) / scale))]
    written = np.array([float(t) for t in texts])
    return texts, xy[q] + (written[:2] - target) * scale, xy[i] + written[2:] * scale


def spiral_bound(original: np.ndarray, start: np.ndarray, end: np.ndarray, centre: np.ndarray,
                 clockwise: bool) -> float:
    """An upper bound, in O(n), of the two-sided (Frechet, hence Hausdorff) distance between the original
    polyline and the arc from ``start`` to ``end`` about ``centre`` as a reader runs it (its radius blended
    linearly with the angle from the start's to the end's: rounding makes them differ), when the vertices
    turn one way about the centre (inf otherwise).  Every point of the polyline is paired with the arc's
    point on the same ray from the centre.  Along a segment the distance ``rho`` to the centre is convex and
    the arc's radius ``r`` lies between its values at the segment's ends, so on a segment
    ``r - rho <= max(r_a, r_b) - rho_min`` and ``rho - r <= max(d_a, d_b) - min(r_a, r_b)``; with equal radii
    this is the exact largest radial gap of each segment.  The ends pair with the ends (a rounded end can
    lie past the last vertex's ray); a vertex between them off the arc's span has no pair (inf)."""
    sign = -1.0 if clockwise else 1.0
    offset = original - centre
    angles = np.unwrap(np.arctan2(offset[:, 1], offset[:, 0]))
    steps = np.diff(angles)
    if not (np.all(steps * sign > 0)) or np.abs(steps).max() >= math.pi / 2:
        return math.inf
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
    r0, r1 = math.hypot(*(start - centre)), math.hypot(*(end - centre))
    sweep = ((a1 - a0) * sign) % (2.0 * math.pi) or 2.0 * math.pi
    lead = (sign * (angles[0] - a0) + math.pi) % (2.0 * math.pi) - math.pi  # the first vertex's angle past the start
    along = (lead + sign * (angles - angles[0])) / sweep
    if np.any((along[1:-1] < 0.0) | (along[1:-1] > 1.0)):  # a vertex off the arc's span: no ray pairs it
        return math.inf
    along = np.clip(along, 0.0, 1.0)
    r = r0 + (r1 - r0) * along
    d = np.hypot(offset[:, 0], offset[:, 1])
    a, u = offset[:-1], np.diff(offset, axis=0)
    t = np.clip(-np.einsum("ij,ij->i", a, u) / np.maximum(np.einsum("ij,ij->i", u, u), 1e-300), 0.0, 1.0)
    nearest = np.hypot(a[:, 0] + t * u[:, 0], a[:, 1] + t * u[:, 1])
    inside = np.maximum(r[:-1], r[1:]) - nearest
    outside = np.maximum(d[:-1], d[1:]) - np.minimum(r[:-1], r[1:])
    # the ends pair with the ends: a rounded end point can lie past the last vertex's ray
    ends = max(math.hypot(*(original[0] - start)), math.hypot(*(original[-1] - end)))
    return float(max(np.abs(d - r).max(), inside.max(), outside.max(), ends))


def _write(program: Program, xy, lines, i: int, q: int, arc: _Arc, edits: dict[int, str],
           removed: list[tuple[int, int]]) -> None:
    """Write the arc over lines ``L(i+1)..L(q)`` into ``edits`` (its first line, the line after it) and
    ``removed`` (the others)."""
    first, end = int(lines[i + 1]), int(lines[q])
    raw = program.lines[first - 1]
    body = raw.rstrip("\r\n")
    words = tokenize(body, program.source, first).words
    x, y, i_text, j_text = _as_written(program, xy, lines, i, q, arc)[0]
    parts = [f"N{w.text}" for w in words if w.letter == "N"]
    parts += [f"G{2 if arc.sweep < 0 else 3}", f"X{x}", f"Y{y}", f"I{i_text}", f"J{j_text}"]
    parts += [f"F{w.text}" for w in words if w.letter == "F"]
    edits[first] = " ".join(parts) + raw[len(body):]
    if end > first:
        removed.append((first + 1, end))
    after = end + 1  # it must not inherit the arc's motion mode
    if after > len(program.lines):
        return
    following = program.lines[after - 1]
    if not sets_motion(program, after):
        # after a leading N word, where a controller expects it (LinuxCNC refuses an N in mid-line)
        number = _LEADING_N.match(following)
        edits.setdefault(after, following[:number.end()] + "G1 " + following[number.end():])


def _verify(text: str, current: Program, original: Program, records: list[ArcRecord], tolerance: float,
            read_options: ReaderOptions | None, start: Reading | None, compiled: bool = False) -> list[ArcRecord]:
    """Re-read the output: every point outside the arcs is where it was, at the feed it had (else
    GCodeError); the arcs that lie farther than the tolerance from the original (each record gets its exact
    deviation) or run at a feed another line they replace did not have."""
    def read(program_text: str) -> Program:
        return (start.snapshot() if start is not None else Reading(current.source, read_options)).read(program_text)

    final = read(text)
    # the input's own arcs compared as chords of one fineness: read both at the check's (the caller's may
    # differ); without arcs (or NURBS) a chord tolerance changes nothing: ``current`` is that reading already
    before = read(text_of(current)) if np.any(current.kinds == Motion.ARC) else current
    replaced = np.zeros(len(current.lines) + 1, bool)  # index = input line
    removed = np.zeros(len(current.lines) + 1, bool)
    for r in records:
        replaced[r.first_line:r.last_line + 1] = True
        removed[r.first_line + 1:r.last_line + 1] = True
    shift = np.cumsum(removed)  # an output line number is the input's less the lines removed before it
    arc_lines = np.array([r.first_line - shift[r.first_line] for r in records])
    kept_before = ~replaced[before.lines_of_points]
    kept_final = ~np.isin(final.lines_of_points, arc_lines)
    if not np.array_equal(before.points[kept_before], final.points[kept_final]):
        raise GCodeError(current.source, 0, "internal check failed: welding arcs moved a point it does not own")
    feed_before, feed_final = before.states.feed[before.lines_of_points], final.states.feed[final.lines_of_points]
    # an arc runs at one feed: every line it replaces must have had it (else it is kept as its lines)
    other_feed = []
    for r, line in zip(records, arc_lines, strict=True):
        replaced_feeds = feed_before[(before.lines_of_points >= r.first_line) & (before.lines_of_points <= r.last_line)]
        if not np.array_equal(replaced_feeds, np.full_like(replaced_feeds, final.states.feed[line]), equal_nan=True):
            other_feed.append(r)
    if other_feed:
        return other_feed
    if not np.array_equal(feed_before[kept_before], feed_final[kept_final], equal_nan=True):
        raise GCodeError(current.source, 0, "internal check failed: welding arcs changed the feed of a move")
    for r, line in zip(records, arc_lines, strict=True):
        a, b = last_point_of(original, np.array([r.first_line, r.last_line]))  # the point each line reaches
        a -= 1  # the arc's start point: the one before its first line's
        new = np.vstack([current.points[a, :2], final.points[final.lines_of_points == line, :2]])
        # the chords lie within CHECK_CHORD of the arc the controller runs: the bound of its distance
        r.deviation_mm = pieced_hausdorff(original.points[a:b + 1, :2], new, compiled=compiled) + CHECK_CHORD
    return [r for r in records if r.deviation_mm > tolerance + 1e-9]
