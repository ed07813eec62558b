"""Sec. 5.3's preprocessing module on a whole program: window its feed moves, classify each window,
smooth the rough ones with the method their category maps to, and rewrite only the moved points.

The edit is a substitution of X/Y numbers on single G1 lines (:mod:`toolpath.gcode.edit`): points
are moved, never added or removed, so every other line, word and comment stays as it was.

Tolerance, both ways and across joins.  Each rough window is smoothed in ``bound`` mode
(:mod:`toolpath.smoothing.problem`), where every point moves at most ``tolerance - rounding`` and the
stretch's two end points stay; writing the numbers at the line's precision moves a point by at most
``rounding`` = half a unit of the last decimal (times sqrt 2 in the plane).  So every point moves at
most ``tolerance``, which bounds the Frechet, hence the two-sided Hausdorff, distance of each changed
stretch; stretches share no segment and everything between them is unchanged, so the whole path is
within ``tolerance`` of the original both ways.  :func:`smooth_program` re-reads its own output and
measures the exact two-sided distance of every stretch before it returns.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from toolpath.gcode.edit import axis_words, movable_lines, program_coordinates, substitute_plain_xy, substitute_xy
from toolpath.gcode.errors import GCodeError
from toolpath.gcode.expressions import controller_name
from toolpath.gcode.program import Lines
from toolpath.gcode.reader import MM_PER_INCH, Program, ReaderOptions
from toolpath.gcode.reading import Reading
from toolpath.gcode.writer import fmt_many
from toolpath.geometry.curvature import local_curvature
from toolpath.geometry.hausdorff import moved_hausdorff
from toolpath.geometry.labels.windows import feed_runs
from toolpath.smoothing.methods import TOGETHER as METHODS_TOGETHER
from toolpath.smoothing.methods import UNTOUCHED, dispatch, smooth_together

MIN_POINTS = 5  # a stretch shorter than this has too few interior points to smooth
DEFAULT_DECIMALS = {False: 3, True: 4}  # mm, inch: where a line gives no decimals of its own


@dataclass(frozen=True)
class RewriteOptions:
    """What ``toolpath smooth`` does; ``smoothing`` is the ``optimize`` config (mean_filter, bezier, nacoa...)."""

    tolerance: float
    smoothing: Mapping
    method: str = "dispatch"
    mapping: Mapping = field(default_factory=lambda: {2: "mean_filter", 3: "bezier", 4: "nacoa"})
    window: int = 50
    seed: int = 0


@dataclass(slots=True)  # a 10-million-line program has 200,000 of them
class WindowRecord:
    """One classified window: its lines, category, what was done and what it cost in deviation."""

    run: int
    first_line: int
    last_line: int
    category: int
    method: str
    curvature_before: float
    curvature_after: float | None = None
    deviation_mm: float = 0.0
    lines_changed: int = 0
    status: str = "unchanged"  # smoothed | unchanged | smooth already | kept: <reason>


@dataclass
class Rewrite:
    """The result: the new text, the per-window records and the runs' points before and after."""

    text: str
    windows: list[WindowRecord]
    runs_before: list[np.ndarray]
    runs_after: list[np.ndarray]
    changed_lines: list[int] | np.ndarray  # input lines changed or removed, ascending
    arcs: list | None = None  # ``--arcs``: :class:`toolpath.smooth.arc_weld.ArcRecord` per arc written
    arcs_note: str | None = None  # why no arc was fitted at all, when so
    arcs_kept_as_lines: int = 0  # arcs the exact re-read check rejected: their G1 lines were kept


def _stretches(lines: np.ndarray, movable: np.ndarray, quiet: np.ndarray, program: Program, first: int,
               last: int) -> tuple[list[tuple[int, int]], str]:
    """Maximal point ranges ``[a, b]`` inside window points ``first..last`` whose interior points each
    sit on their own movable line, with nothing between their lines that moves the tool or changes a
    mode; the stretch's end point is fixed and its line must be a G1 stating X and Y (:func:`_closes`)."""
    if not program.states.absolute[int(lines[first])]:
        return [], "incremental (G91) moves are kept as they are"

    def gap_ok(k: int) -> bool:  # nothing happens on the lines strictly between points k - 1 and k
        lo, hi = int(lines[k - 1]), int(lines[k])
        return lo < hi and quiet[hi - 1] - quiet[lo] == 0

    lo, hi = lines[first:last + 1][:-1].astype(np.int64), lines[first:last + 1][1:].astype(np.int64)
    gap = np.zeros(last + 2, bool)  # gap[k]: nothing happens strictly between points k - 1 and k
    gap[first + 1:last + 1] = (lo < hi) & (quiet[hi - 1] - quiet[lo] == 0)
    free = np.zeros(last + 1, bool)
    inner = np.arange(first + 1, last)
    # a point moves only on a line in absolute mode: a window G91 switches on in the middle keeps its tail
    absolute = program.states.absolute[lines[first:last + 1].astype(np.int64)]
    free[inner] = movable[lines[inner].astype(np.int64) - 1] & gap[inner] & gap[inner + 1] & absolute[1:-1]
    out, k, reason = [], first, "no movable G1 lines (arcs, Z moves or words the rewrite does not own)"
    while k < last:
        if not free[k + 1]:
            k += 1
            continue
        a = k
        while k + 1 < last and free[k + 1]:
            k += 1
        b = k + 1
        # the line that ends the stretch starts at a moved point: it must be a G1 (an arc's centre would
        # move with its start) and state X and Y itself (later lines may rely on them modally)
        while b > a + 1 and not _closes(program, movable, lines, b):
            b -= 1
        if b - a + 1 >= MIN_POINTS:
            out.append((a, b))
        else:
            reason = "too few movable G1 lines in a row"
    return out, reason


def _quiet_prefix(program: Program) -> np.ndarray:
    """Cumulative count of lines that move the tool or change absolute / units / offsets (index = line)."""
    counts = np.bincount(program.lines_of_points, minlength=len(program.lines) + 1)
    busy = counts > 0
    states = program.states
    busy[1:] |= ((states.absolute[1:] != states.absolute[:-1]) | (states.inch[1:] != states.inch[:-1])
                 | (states.offset_id[1:] != states.offset_id[:-1]))
    return np.cumsum(busy)


def switch_stable(program: Program, read_options: ReaderOptions | None, start: Reading | None) -> np.ndarray:
    """Per line (index = line, 0 the start): True where the line is no ``/`` line and the tool stands at
    the same place after it with the block-delete switch off (``program``, as read) and on.  Without a
    ``/`` line, every line."""
    lines = program.lines
    text = lines.text if isinstance(lines, Lines) else "".join(lines)
    deleted = np.zeros(len(lines) + 1, bool)
    if "/" not in text:  # most programs: no line to look at
        return ~deleted
    deleted[1:] = [raw.lstrip(" \t").startswith("/") for raw in lines]
    if not deleted.any():
        return ~deleted
    switched = replace(read_options or ReaderOptions(), block_delete=True)
    reading = start.with_options(switched) if start is not None else Reading(program.source, switched)
    other = reading.read(text)
    return np.all(other.states.position == program.states.position, axis=1) & ~deleted


#: a read of a system parameter: LinuxCNC's #5000-#5999 hold what the controller knows (the current position
#: #5420-#5428, G28 / G30 / G92 and work offsets, probe results, the tool), as do its read-only named
#: parameters and _hal[] / _ini[] reads; the reader does not know them.  Matched on the line without
#: comments or blanks, in lower case (LinuxCNC reads a line so).
_SYSTEM_PARAMETER = re.compile(r"#0*5\d{3}(?!\d)|#<(_[a-z_\[\].\-0-9]*)>")
_COMMENT = re.compile(r"\([^)]*\)?|;.*")


def controller_state_read(program: Program) -> tuple[int, str] | None:
    """The first line (and the word) that reads a parameter only the controller knows, or None: from there
    on the reader's path is not the controller's, so nothing there or after it is smoothed."""
    if isinstance(program.lines, Lines) and "#" not in program.lines.text:
        return None  # one scan of the text, not a Python pass over every line: most programs read no parameter
    for number, raw in enumerate(program.lines, start=1):
        if "#" not in raw:
            continue
        line = re.sub(r"\s+", "", _COMMENT.sub(" ", raw)).lower()
        for found in _SYSTEM_PARAMETER.finditer(line):
            if found.group(1) is None or controller_name(found.group(1)):
                return number, found.group(0)
    return None


def _closes(program: Program, movable: np.ndarray, lines: np.ndarray, b: int) -> bool:
    line = int(lines[b])
    if not movable[line - 1] or not program.states.absolute[line] or (b + 1 < len(lines) and lines[b + 1] == line):
        return False
    return set(axis_words(program.lines[line - 1].rstrip("\r\n"))) == {"X", "Y"}


def line_decimals(program: Program, line: int) -> int:
    """Decimals a moved point is written with: the line's own, at least the default of its units."""
    default = DEFAULT_DECIMALS[bool(program.states.inch[line - 1])]
    if program.plain is not None and program.plain[line - 1]:
        return max(int(program.xy_decimals[line - 1].max()), default)
    words = axis_words(program.lines[line - 1].rstrip("\r\n"))
    return max([w.decimals for w in words.values()] + [default])


def decimals_of(program: Program, lines: np.ndarray) -> np.ndarray:
    """:func:`line_decimals` of many lines at once (the scanner's plain lines from its columns)."""
    lines = np.asarray(lines, np.int64)
    inch = program.states.inch[lines - 1].astype(bool)
    out = np.where(inch, DEFAULT_DECIMALS[True], DEFAULT_DECIMALS[False]).astype(np.int64)
    plain = program.plain[lines - 1] if program.plain is not None else np.zeros(len(lines), bool)
    out[plain] = np.maximum(program.xy_decimals[lines[plain] - 1].max(axis=1), out[plain])
    for k in np.flatnonzero(~plain):
        out[k] = line_decimals(program, int(lines[k]))
    return out


def rounding_margins(program: Program, lines: np.ndarray, decimals: np.ndarray) -> np.ndarray:
    """Per line, the most that writing a point at the line's precision moves it, in mm."""
    half_unit = np.array([0.5 * 10.0 ** -d for d in range(int(decimals.max(initial=0)) + 1)])
    scale = np.where(program.states.inch[np.asarray(lines, np.int64) - 1], MM_PER_INCH, 1.0)
    return half_unit[decimals] * scale * np.sqrt(2.0)


def _method_for(category: int, options: RewriteOptions) -> str:
    if category <= 1:
        return UNTOUCHED
    return dispatch(category, options.mapping) if options.method == "dispatch" else options.method


def smooth_program(program: Program, classify: Callable[[np.ndarray], np.ndarray], options: RewriteOptions,
                   read_options: ReaderOptions | None = None,
                   progress: Callable[[list], list] = lambda items: items, start: Reading | None = None,
                   stop: tuple[int, str] | None = None) -> Rewrite:
    """Classify every window of ``program``'s feed runs and smooth the rough ones within the tolerance.

    ``start``: for a part of a program (:mod:`toolpath.smooth.stream`), the reading its output is
    re-read from (the modal state and parameters where the part begins).  ``stop``: (line, word) from
    which no window is smoothed (:func:`controller_state_read`; line 0: the whole part).

    ``classify`` maps windows (N, window, 2) in mm, relative to their first point, to Table 1
    categories 1-4.  Raises :class:`GCodeError` when the tolerance is finer than the program's
    numbers can express.
    """
    if options.method == "none":  # `--method none`: nothing smoothed (`--arcs` alone, ArcWelder's job)
        runs_xy = [xy for xy, _ in feed_runs(program)]
        return Rewrite(program.lines.joined({}), [], runs_xy, runs_xy, [])
    movable, quiet = movable_lines(program), _quiet_prefix(program)
    # a window a `/` line touches runs differently by the block-delete switch: kept whole
    switched = np.cumsum(~switch_stable(program, read_options, start))
    runs = [(xy, lines) for xy, lines in feed_runs(program)]
    size = options.window
    records: list[WindowRecord] = []
    jobs: list[tuple[int, int, int, WindowRecord]] = []  # run, first and last point, window
    for r, (xy, lines) in enumerate(runs):
        count = 0 if len(xy) < size else (len(xy) - size) // size + 1
        if not count:
            continue
        starts = np.arange(count) * size
        windows = xy[:count * size].reshape(count, size, 2)
        local = windows - windows[:, :1]
        categories = np.asarray(classify(local)).astype(int)
        curvatures = local_curvature(local).tolist()
        for s, category, curvature in zip(starts, categories, curvatures, strict=True):
            e = s + size - 1
            record = WindowRecord(r, int(lines[s]), int(lines[e]), int(category), _method_for(int(category), options),
                                  curvature)
            records.append(record)
            if record.method == UNTOUCHED:
                record.status = "smooth already"
                continue
            if stop is not None and int(lines[e]) >= stop[0]:
                where = f"line {stop[0]}" if stop[0] else "an earlier part"
                record.status = f"kept: {stop[1]} at {where} reads what only the controller knows: smoothing stops"
                continue
            if switched[int(lines[e])] - (switched[int(lines[s]) - 1] if lines[s] > 0 else 0) > 0:
                record.status = "kept: block delete (/) in the window: the path differs with the switch on"
                continue
            if (blind := np.flatnonzero(program.states.blind[int(lines[s]):int(lines[e]) + 1])).size:
                # the reader read past a construct it does not follow (toolpath.gcode.passing): the lines stay
                why = program.states.reason(int(lines[s]) + int(blind[-1]))
                record.status = f"kept: {why}, passed through as written"
                continue
            stretches, reason = _stretches(lines, movable, quiet, program, s, e)
            if not stretches:
                record.status = f"kept: {reason}"
            for a, b in stretches:
                jobs.append((r, int(a), int(b), record))
    moved_lines = [runs[r][1][a + 1:b].astype(np.int64) for r, a, b, _ in jobs]
    flat = np.concatenate(moved_lines) if jobs else np.zeros(0, np.int64)
    decimals = decimals_of(program, flat)
    margins = rounding_margins(program, flat, decimals)
    bounds = np.cumsum([0] + [len(lines) for lines in moved_lines])
    configs = []
    for k, (r, a, _, _) in enumerate(jobs):
        margin = margins[bounds[k]:bounds[k + 1]].max()
        if options.tolerance - margin <= 0:
            raise GCodeError(program.source, int(runs[r][1][a + 1]), f"the tolerance {options.tolerance} mm is "
                             f"finer than this line's numbers can express ({margin:.2g} mm)")
        configs.append({**options.smoothing, "tolerance": options.tolerance - margin})
    moved: list[np.ndarray | None] = [None] * len(jobs)
    for unit in progress(_units(jobs, configs)):  # _verify checks every result, after rounding
        _, a, _, record = jobs[unit[0]]
        windows = [runs[r][0][a:b + 1] for r, a, b, _ in (jobs[k] for k in unit)]
        results = smooth_together(windows, record.method, configs[unit[0]], "bound",
                                  [options.seed + jobs[k][1] for k in unit])
        for k, result in zip(unit, results, strict=True):
            _, a, b, record = jobs[k]
            moved[k] = result.points[1:-1]
            record.status, record.lines_changed = "smoothed", record.lines_changed + int(b - a - 1)
    edits = _edits(program, flat, np.concatenate(moved) if moved else np.zeros((0, 2)), decimals)
    result = _verify(program, program.lines.joined(edits), runs, records, jobs, edits, options, read_options, start)
    # a window whose LocalCurvature did not fall (as written, rounding included) is kept as it was
    no_gain = {id(r) for r in records if r.status == "smoothed" and r.curvature_after >= r.curvature_before}
    if not no_gain:
        return result
    keep = [k for k, job in enumerate(jobs) if id(job[3]) not in no_gain]
    for record in records:
        if id(record) in no_gain:
            record.status, record.lines_changed = "kept: no gain (its LocalCurvature would not fall)", 0
    mask = np.repeat(np.isin(np.arange(len(jobs)), keep), [len(lines) for lines in moved_lines])
    points = np.concatenate([moved[k] for k in keep]) if keep else np.zeros((0, 2))
    edits = _edits(program, flat[mask], points, decimals[mask])
    return _verify(program, program.lines.joined(edits), runs, records, [jobs[k] for k in keep], edits, options,
                   read_options, start)


MOST_AT_ONCE = 32  # windows smoothed side by side at most (a few MB of NACOA's arrays)


def _units(jobs: list, configs: list[dict]) -> list[list[int]]:
    """Jobs in the order they are run: side by side in groups of one method, stretch length and tolerance
    where the method allows it (:data:`toolpath.smoothing.methods.TOGETHER`; each keeps its own seed,
    so its result is the one it gets alone), else one at a time."""
    units, open_groups = [], {}
    for k, (_, a, b, record) in enumerate(jobs):
        if record.method not in METHODS_TOGETHER:
            units.append([k])
            continue
        key = (record.method, b - a, configs[k]["tolerance"])
        if key not in open_groups or len(open_groups[key]) == MOST_AT_ONCE:
            open_groups[key] = []
            units.append(open_groups[key])
        open_groups[key].append(k)
    return units


def _edits(program: Program, lines: np.ndarray, points: np.ndarray, decimals: np.ndarray) -> dict[int, str]:
    """The new text of each moved line: its X/Y numbers, in its own frame and units, at its precision; a
    line whose numbers round back to its own text is left out (it is not changed, nor counted as changed)."""
    values = program_coordinates(program, lines, points)
    plain = program.plain[lines - 1] if program.plain is not None else np.zeros(len(lines), bool)
    numbers = fmt_many(values.ravel(), np.repeat(decimals, 2))
    text, starts = program.lines.text, program.lines.starts  # slices of the text, taken at once
    raws = [text[a:b] for a, b in zip(starts[lines - 1].tolist(), starts[lines].tolist(), strict=True)]
    edits = {}
    for k, (line, raw, fast) in enumerate(zip(lines.tolist(), raws, plain.tolist(), strict=True)):
        x_text, y_text = numbers[2 * k], numbers[2 * k + 1]
        new = substitute_plain_xy(raw, x_text, y_text) if fast else substitute_xy(raw, {"X": x_text, "Y": y_text})
        if new != raw:
            edits[line] = new
    return edits


def _verify(program: Program, text: str, runs, records, jobs, edits, options, read_options, start) -> Rewrite:
    """Re-read the output: every point a kept line reaches is where it was, the moved points are
    taken from the re-read program, and every stretch is measured both ways against the original."""
    reread = (start.snapshot() if start is not None else Reading(program.source, read_options)).read(text)
    moved_points = np.isin(program.lines_of_points, np.fromiter(edits, int, len(edits)))
    if reread.points.shape != program.points.shape or not np.array_equal(reread.points[~moved_points],
                                                                         program.points[~moved_points]):
        raise GCodeError(program.source, 0, "internal check failed: the rewrite moved a point it does not own")
    point_of_line = np.full(len(program.lines) + 1, -1)
    point_of_line[program.lines_of_points] = np.arange(len(program.lines_of_points))
    new_runs = []
    for xy, lines in runs:
        new = xy.copy()
        changed = np.isin(lines, np.fromiter(edits, int, len(edits)))
        new[changed] = reread.points[point_of_line[lines[changed]], :2]
        new_runs.append(new)
    worst: dict[int, float] = {}
    deviations = moved_hausdorff([runs[r][0][a:b + 1] for r, a, b, _ in jobs],
                                 [new_runs[r][a:b + 1] for r, a, b, _ in jobs]) if jobs else []
    for (r, a, _, record), deviation in zip(jobs, np.asarray(deviations).tolist(), strict=True):
        if deviation > options.tolerance + 1e-9:
            raise GCodeError(program.source, int(runs[r][1][a + 1]), f"internal check failed: a smoothed "
                             f"stretch lies {deviation:.6f} mm from the original, over {options.tolerance} mm")
        worst[id(record)] = max(worst.get(id(record), 0.0), deviation)
    after: dict[int, list[float]] = {}  # per run, LocalCurvature of each window of the new path
    size = options.window
    for r, new in enumerate(new_runs):
        count = len(new) // size
        windows = new[:count * size].reshape(count, size, 2)
        after[r] = local_curvature(windows - windows[:, :1]).tolist() if count else []
    counters: dict[int, int] = {}
    for record in records:
        record.deviation_mm = worst.get(id(record), 0.0)
        k = counters.get(record.run, 0)
        counters[record.run] = k + 1
        record.curvature_after = after[record.run][k]
    return Rewrite(text, records, [xy for xy, _ in runs], new_runs, sorted(edits))
