"""``toolpath smooth`` on a program of any length: read, smooth and hand back one part at a time.

The file is read in parts of about :data:`PART_BYTES` (:func:`toolpath.gcode.reading.text_parts`),
one interpreter carried through them.  A part is smoothed up to the last window boundary of the
feed run still open at its end; the lines from there on, already read, wait and go with the next
part (nothing is read twice), so every window is the window the whole program would have (the
run's windows are counted from its start, 50 points each).  Memory is that of a part, whatever
the length of the program.

Where a window boundary falls inside a line's points (an arc's chords), the window before it waits too,
so the next part still starts on a window's first point. Where this cannot be exact, it says so here:
lines that would wait but set a parameter (``#1 = ..``), G28.1 / G30.1 or G90.1 / G91.1, or hold a NURBS
line (G6.2 and its K lines, G5.2 / G5.3), do not wait (their effect could not be replayed), and the next
part starts its windows afresh; a part never ends inside a NURBS block. The machining time plans each
part's feed runs from rest to rest, so a run longer than a part is timed in pieces, before and after
alike.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from toolpath.gcode.program import Motion, Program
from toolpath.gcode.reader import ReaderOptions
from toolpath.gcode.reading import Reading, text_parts
from toolpath.geometry.labels.windows import feed_runs
from toolpath.smooth.rewrite import Rewrite, RewriteOptions, controller_state_read, smooth_program

PART_BYTES = 8 << 20  # ~350,000 lines of CAM output: a few tens of MB of working memory
ARC_PART_BYTES = 2 << 20  # --arcs re-reads each part twice to check it: a 1,000,000-line program peaks at
#                           218 MB (4 MB: 285, 8 MB: 401) for 518 lines out (513, 509: an arc ends at a part)
# lines whose effect a resumed reading could not replay from the modal state of their row
_STATEFUL = re.compile(r"#\s*(?:[\d.]+|<[^>]*>)\s*="  # a parameter set
                       r"|[gG]\s*0*(?:28|30|90|91)\s*\.\s*1"  # stored positions, arc centres
                       r"|[gG]\s*0*(?:6\s*\.\s*2|5\s*\.\s*[23])"  # NURBS
                       r"|^\s*(?:[nN][\d.]+\s*)?[kK]", re.MULTILINE)  # a line of a NURBS block


@dataclass
class Part:
    """One smoothed part: its program (lines numbered from 1, ``first_line`` in the file), the result
    and the reading its output re-reads from."""

    program: Program
    result: Rewrite
    start: Reading
    restarts: bool = False  # the feed run open at its end starts its windows afresh in the next part


def _cut(program: Program, window: int) -> tuple[int, bool]:
    """How many of the part's lines to smooth now: all but those from the first point of the open
    run's unfinished window on (or all, where those lines cannot wait); and whether the open run's
    windows restart in the next part because of that."""
    count = len(program.lines)
    if not len(program.kinds) or program.kinds[-1] == Motion.RAPID:
        return count, False  # no feed run open at the end
    runs = feed_runs(program)
    xy, lines = runs[-1]
    k = (len(xy) // window) * window
    if k == len(xy):
        k -= window  # let the last whole window wait too: the next part starts on one of its points
    # the part after the cut must start with the window's first point: where that point is not the
    # first of its line (an arc's chords, a repeated point), let the window before wait as well
    while k > 0:
        line = int(lines[k])
        first = int(np.searchsorted(program.lines_of_points, line, side="left"))
        if lines[k - 1] != line and np.array_equal(program.points[first, :2], xy[k]):
            break
        k -= window
    line = int(lines[max(k, 0)])
    rest = program.lines.text[program.lines.starts[line - 1]:]
    # a state the table's rows do not hold (read past, another plane) cannot be resumed from a row either
    if _STATEFUL.search(rest) or program.states.special[line - 1:].any():
        return count, True
    return line - 1, False


def smooth_parts(path: Path, classify: Callable[[np.ndarray], np.ndarray], options: RewriteOptions,
                 read_options: ReaderOptions | None = None, part_bytes: int = PART_BYTES,
                 progress: Callable[[list], list] = lambda items: items, units: str | None = None) -> Iterator[Part]:
    """Every part of the program at ``path``, smoothed (:func:`toolpath.smooth.rewrite.smooth_program`);
    ``units`` ("mm" or "inch"): the units the program runs in until it sets its own (G20 / G21).

    Raises
    ------
    GCodeError
        Naming the file's line, for anything the reader refuses.
    OSError
        When the file cannot be read.
    """
    reading = Reading(str(path), read_options)
    reading.interp.inch = units == "inch"  # the control's units until the program says G20 / G21
    start = reading.snapshot()
    waiting: Program | None = None
    stop: tuple[int, str] | None = None  # from where a system parameter is read: nothing smoothed
    parts = text_parts(path, part_bytes)
    text = next(parts, None)
    while text is not None:
        following = next(parts, None)
        program = reading.read(text, final=following is None)
        while reading.interp.nurbs is not None and following is not None:  # a NURBS block runs on: read on
            text, following = following, next(parts, None)
            program = program.then(reading.read(text, final=following is None))
        if waiting is not None:
            program = waiting.then(program)
        text = following
        count, restarts = (len(program.lines), False) if text is None else _cut(program, options.window)
        head, waiting = program.split(count)
        if count == 0:  # the whole part is one unfinished window: read on
            continue
        if stop is None and (found := controller_state_read(head)) is not None:
            stop = found
        result = smooth_program(head, classify, options, read_options, progress, start=start, stop=stop)
        if stop is not None:
            stop = (0, stop[1])  # the later parts: kept whole
        yield Part(head, result, start, restarts)
        start = reading.resume_at(waiting.states, 0, waiting.first_line - 1)


@dataclass
class Combined:
    """The parts' results as one: windows and arcs numbered by the file's lines, runs numbered in order
    (a run longer than a part counts once per part), the paths kept only where they are drawn."""

    keep_paths: bool = False
    lines: int = 0
    runs: int = 0
    before: float | None = 0.0
    after: float | None = 0.0
    why: str | None = None
    parts: int = 0

    def __post_init__(self) -> None:
        self.windows: list = []
        self.arcs: list | None = None
        self.arcs_note: str | None = None
        self.arcs_kept_as_lines = 0
        self.changed: list[np.ndarray] = []
        self.runs_before: list[np.ndarray] = []
        self.runs_after: list[np.ndarray] = []
        self.restarts: list[int] = []  # lines where windows restart because the lines before could not wait
        self.passed: list[str] = []  # what the reader read past, in order (toolpath.gcode.passing)

    @property
    def changed_lines(self) -> np.ndarray:
        return np.concatenate(self.changed) if self.changed else np.zeros(0, np.int64)

    def add(self, part: Part, times: tuple) -> None:
        """Take one part's result; ``times`` is its (before, after, why) machining time."""
        from dataclasses import replace

        shift, result = part.program.first_line - 1, part.result
        for w in result.windows:
            w.first_line, w.last_line, w.run = w.first_line + shift, w.last_line + shift, w.run + self.runs
        self.windows.extend(result.windows)
        states = part.program.states
        for reason in (states.reasons[k] for k in np.unique(states.reason_id[states.blind]) if k):
            if reason not in self.passed:
                self.passed.append(reason)
        if result.arcs is not None:
            self.arcs = (self.arcs or []) + [replace(a, first_line=a.first_line + shift, last_line=a.last_line + shift)
                                             for a in result.arcs]
            self.arcs_note = self.arcs_note or result.arcs_note
            self.arcs_kept_as_lines += result.arcs_kept_as_lines
        self.changed.append(np.asarray(result.changed_lines, np.int64) + shift)
        self.lines += len(part.program.lines)
        self.parts += 1
        if part.restarts:
            self.restarts.append(self.lines + 1)
        self.runs += len(result.runs_before)
        if self.keep_paths:
            self.runs_before.extend(result.runs_before)
            self.runs_after.extend(result.runs_after)
        before, after, why = times
        if why is not None or self.why is not None:
            self.before = self.after = None
            self.why = self.why or why
        else:
            self.before += before
            self.after += after
