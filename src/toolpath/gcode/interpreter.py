"""The RS-274 interpreter: one line at a time (and plain motion runs vectorised) into tool positions.

The public entry points are :func:`toolpath.gcode.reader.read_text` / ``read_file`` and, for a program
read in parts, :class:`toolpath.gcode.reading.Reading`; this module is the dialect they read.

Supported: LinuxCNC's numbered and named parameters and ``[ ]`` expressions
(:mod:`toolpath.gcode.expressions`), G0/G1/G2/G3 (arcs by I/J or R, both directions, full circles, helices, P turns),
G17, G20/G21 (points are always returned in mm), G90/G91, G90.1/G91.1, G92 offsets, modal motion and
modal coordinates (also before any G word), F/S/T/M/H/D words, N words, comments, ``%``, block delete
``/``, tabs, LF, CRLF and lone-CR line ends and a UTF-8 BOM; G28/G30 returns to their stored positions
(G28.1/G30.1 store them); NURBS blocks, LinuxCNC's G5.2/G5.3 and G6.2 (:mod:`toolpath.gcode.nurbs`),
discretised within the chord tolerance. Work offsets (G54-G59), tool length offsets (G43/G49) and
path-control modes (G61/G64) are accepted and do not move the XY path. After M2 or M30 the program has
ended, as on a controller: later lines are kept in ``Program.lines`` but not read; so after a ``%`` that
closes the program (any ``%`` but a leading one).

Limits, properties of the program rather than of the machine: a line of at most 4096 characters
(:data:`toolpath.gcode.text.MAX_LINE_LENGTH`), word values of magnitude at most 1e9
(:data:`toolpath.gcode.lexer.MAX_WORD_VALUE`), expressions nested at most 32 deep, an arc of at most
a million chords (:data:`toolpath.gcode.arcs.MAX_ARC_POINTS`; the count follows from its length and
the chord tolerance), a program of at most 20 million points (:data:`MAX_POINTS`).  M words are
whole numbers 0-199, G words have one decimal at most, an arc's P is a whole number >= 1.

Rejected with a :class:`GCodeError` naming ``file:line``: G18/G19, O-words,
G5/G5.1 splines, cutter compensation (G41/G42), canned cycles (G73-G89), G53, probing, homing,
M98 / M99 (each read past instead with ``ReaderOptions.pass_through``: :mod:`toolpath.gcode.passing`)
and every malformed word.
"""

from __future__ import annotations

import numpy as np

from toolpath.gcode.arcs import RADIUS_TOLERANCE, centre_arc_problem, centre_from_radius, discretise_arc
from toolpath.gcode.errors import GCodeError
from toolpath.gcode.expressions import Parameters
from toolpath.gcode.lexer import Block, Word, tokenize
from toolpath.gcode.nurbs import NurbsBlock, NurbsMotion
from toolpath.gcode.options import DIALECTS, ReaderOptions  # noqa: F401 - read from here too
from toolpath.gcode.passing import PassThrough
from toolpath.gcode.program import MM_PER_INCH, Motion, StateTable
from toolpath.gcode.scanner import Scan

# The most points one program may expand to (480 MB of coordinates): a program past it is refused by
# name, not read until the machine runs out of memory.
MAX_POINTS = 20_000_000


_MOTION = {0: 0, 1: 1, 2: 2, 3: 3}
# G8: lathe radius mode, the default; G96 / G97: spindle speed modes; G43.1 / G43.2 (below): tool length
# offsets, whose axis words are offsets, not a move
_ACCEPTED_G = {4, 8, 17, 40, 43, 49, 54, 55, 56, 57, 58, 59, 61, 64, 80, 93, 94, 95, 96, 97, 98, 99}
_REJECTED_G = {
    5: "of the G5 group only G5.2 / G5.3 (NURBS) are supported", 6: "of the G6 group only G6.2 (NURBS) is supported",
    18: "only the XY plane (G17) is supported, not G18", 19: "only the XY plane (G17) is supported, not G19",
    41: "cutter compensation (G41) is not supported", 42: "cutter compensation (G42) is not supported",
    53: "machine coordinates (G53) are not supported",
}
_CANNED = set(range(73, 90)) - {80}
_UNSUPPORTED_M = {98: "subprogram calls (M98) are not supported", 99: "M99 (subprogram return) is not supported"}


class Interpreter(NurbsMotion, PassThrough):
    """Modal state machine over the blocks of one program."""

    def __init__(self, source: str, options: ReaderOptions) -> None:
        self.src = source
        self.opt = options
        self.motion: int | None = options.initial_motion
        self.absolute = True
        self.arc_absolute = False
        self.inch = False
        self.units_seen: set[str] = set()
        self.pos = np.zeros(3)
        self.offset = np.zeros(3)
        self.feed: float | None = None
        self.ended = False
        self.started = False  # a line with words (or a '%') has been seen
        self.params = Parameters(controller_as_zero=options.pass_through)  # toolpath smooth stops there
        self.nurbs: NurbsBlock | None = None  # a NURBS block being read
        self.table: StateTable | None = None  # the rows of the text being read, for a closing NURBS block
        self.text = ""  # the text being read, for the lines run_plain hands to run_block
        self.base = 0  # lines of the program before that text: line numbers are the program's
        # per emitted block: its points (k, 3), their kinds and lines, concatenated at the end
        self.points: list[np.ndarray] = []
        self.kinds: list[np.ndarray] = []
        self.point_lines: list[np.ndarray] = []
        self.total = 0
        self.init_passing()

    def record(self, table: StateTable, row: int) -> None:
        blind = self.blind()
        table.put(row, self.motion, self.absolute, self.inch, self.pos, self.offset, self.feed, blind, self.special(),
                  self.why if blind else "")

    def fail(self, lineno: int, message: str) -> GCodeError:
        return GCodeError(self.src, lineno, message)

    def _g_codes(self, words: list[Word], lineno: int) -> tuple[int | None, list[float]]:
        motion, others = None, []
        for w in words:
            if w.letter != "G":
                continue
            code = round(w.value, 1)
            if abs(w.value - code) > 1e-6 or w.value < 0:
                raise self.fail(lineno, f"G{w.text} is not a G-code (one decimal at most)")
            major = int(code)
            if code == major and major in _MOTION:
                if motion is not None:
                    raise self.fail(lineno, "two motion G words on one line")
                motion = major
            elif code in (5.2, 6.2):  # NURBS (toolpath.gcode.nurbs)
                others.append(code)
            elif code == 5.3:
                raise self.fail(lineno, "G5.3 without a G5.2 block to end")
            elif self.opt.pass_through and (kind := self.pass_codes(code, major)) is not None:
                if kind == "motion":
                    if motion is not None:
                        raise self.fail(lineno, "two motion G words on one line")
                    motion = major
                else:
                    others.append(code)
            elif major in _REJECTED_G:
                raise self.fail(lineno, _REJECTED_G[major])
            elif code == major and major in _CANNED:
                raise self.fail(lineno, f"canned cycle G{major} is not supported")
            elif code in (20, 21, 90, 91, 90.1, 91.1, 92, 92.1, 92.2, 92.3, 28, 28.1, 30, 30.1, 43.1, 43.2) or (
                code == major and major in _ACCEPTED_G
            ):
                others.append(code)
            else:
                raise self.fail(lineno, f"G{w.text} is not supported")
        return motion, others

    def run_block(self, block: Block, lineno: int) -> None:
        self.opaque = False
        if block.percent:
            # a leading '%' opens the program, any later one ends it (LinuxCNC, Fanuc)
            self.ended = self.ended or self.started
            self.started = True
            return
        self.started = self.started or bool(block.words or block.assignments)
        if self.ended or self.stopped or (block.block_delete and self.opt.block_delete):
            return
        for key, value in block.assignments:  # after every value on the line was read with the old ones
            self.params.set(key, value)
        if self.nurbs is not None and self.nurbs.kind == "G5.2":
            if block.words:
                self._g5_line(block.words, lineno)
            return
        if self.nurbs is not None:  # a K line continues the block (G6.2 repeated, without P, is modal)
            if any(w.letter == "K" for w in block.words) and not any(w.letter == "P" for w in block.words):
                self._nurbs_line(block.words, lineno)
                return
            if block.words:
                self.close_nurbs(lineno - 1)
        seen: set[str] = set()
        for w in block.words:
            if w.letter in seen and w.letter not in "GM":
                raise self.fail(lineno, f"word {w.letter} appears twice on one line")
            seen.add(w.letter)
        words = list(block.words)
        if self.opt.dialect == "fanuc" and not self.opt.whole_integer_words:
            self.check_decimal_points(words, lineno)
        values = {w.letter: w.value for w in words if w.letter not in "GM"}
        motion, others = self._g_codes(words, lineno)
        if values.keys() & set("ABCUVWE@^"):
            self.other_words(values, {int(w.value) for w in words if w.letter == "M"}, lineno)
        for w in words:
            if w.letter == "M":
                if w.value != int(w.value) or not 0 <= w.value <= 199:
                    raise self.fail(lineno, f"M{w.text} is not an M-code (a whole number 0-199)")
                code = int(w.value)
                if code in _UNSUPPORTED_M and self.opt.pass_through:
                    self.stop_following(lineno, f"M{code} (subprogram {'call' if code == 98 else 'return'})")
                    return
                if code in _UNSUPPORTED_M:
                    raise self.fail(lineno, _UNSUPPORTED_M[code])
                if code in (2, 30):
                    self.ended = True
        # Modal settings take effect before the motion on the same line (RS-274 order of execution).
        for code in others:
            if code == 20:
                self.inch = True
                self.units_seen.add("inch")
            elif code == 21:
                self.inch = False
                self.units_seen.add("mm")
            elif code == 90:
                self.absolute = True
            elif code == 91:
                self.absolute = False
            elif code == 90.1:
                self.arc_absolute = True
            elif code == 91.1:
                self.arc_absolute = False
            elif code == 80:
                self.motion = None
        if "F" in values:
            self.feed = values["F"] * (MM_PER_INCH if self.inch else 1.0)
        if self.opt.pass_through and self.read_past(motion, others, values, lineno):
            return
        if 6.2 in others:
            self._open_nurbs(motion, values, lineno)
            return
        if 5.2 in others:
            self._open_g5(motion, values, lineno)
            return
        if 43.1 in others or 43.2 in others:  # a tool length offset: its words are the offset
            return
        if 92 in others or 92.1 in others or 92.2 in others:
            self._set_offset(others, values)
            if 92 in others:
                self.offset_set(values)
            return
        for code, first in ((28, 5161), (30, 5181)):
            if code + 0.1 in others:  # G28.1 / G30.1: remember where the tool is
                for i in range(3):
                    self.params.set(first + i, float(self.pos[i]))
                self.stored[code] = not self.unknown
                return
            if code in others:
                self._home(values, first, lineno)
                if self.opt.pass_through:
                    self.homed(code, [a for a in "XYZ" if a in values] or "XYZ", lineno)
                return
        if motion is not None:
            self.motion = motion
        axes = [a for a in "XYZ" if a in values]
        if not axes:
            if motion in (2, 3) and not self.ended:  # LinuxCNC: the end is the start, a full circle
                self._move(values, lineno)
            return
        if self.motion is None:
            raise self.fail(lineno, "axis words with no motion mode in effect (after G80 or a NURBS block)")
        self._move(values, lineno)

    def _home(self, values: dict[str, float], first: int, lineno: int) -> None:
        """G28 / G30 (LinuxCNC): with axis words, a rapid to that point, then a rapid of those axes
        only to the stored position (parameters 5161-5163 / 5181-5183, 0 until G28.1 / G30.1);
        without, a rapid of every axis there.  The stored position is in the reader's frame
        (no G92 offset), mm, as a machine configured in mm keeps it."""
        axes = [i for i, a in enumerate("XYZ") if a in values]
        if axes:
            via = self._target(values)
            self._emit(via[None, :], Motion.RAPID, lineno)
            self.pos = via
        home = self.pos.copy()
        for i in axes or range(3):
            home[i] = self.params.get(first + i)
        self._emit(home[None, :], Motion.RAPID, lineno)
        self.pos = home

    def _set_offset(self, others: list[float], values: dict[str, float]) -> None:
        if 92 in others:
            scale = MM_PER_INCH if self.inch else 1.0
            for i, a in enumerate("XYZ"):
                if a in values:  # program coordinate of the current point becomes the given value
                    self.offset[i] = self.pos[i] - values[a] * scale
        else:
            self.offset[:] = 0.0

    def _target(self, values: dict[str, float]) -> np.ndarray:
        scale = MM_PER_INCH if self.inch else 1.0
        target = self.pos.copy()
        for i, a in enumerate("XYZ"):
            if a in values:
                v = values[a] * scale
                target[i] = v + self.offset[i] if self.absolute else self.pos[i] + v
        return target

    def _move(self, values: dict[str, float], lineno: int) -> None:
        target = self._target(values)
        if self.motion in (0, 1):
            kind = Motion.RAPID if self.motion == 0 else Motion.FEED
            self._emit(target[None, :], kind, lineno)
        else:
            self._arc(target, values, lineno)
        self.pos = target
        self.moved(values)

    def _arc(self, target: np.ndarray, values: dict[str, float], lineno: int) -> None:
        clockwise = self.motion == 2
        scale = MM_PER_INCH if self.inch else 1.0
        if "R" in values:
            if "I" in values or "J" in values:
                raise self.fail(lineno, "an arc takes either R or I/J, not both")
            try:
                centre = centre_from_radius(self.pos, target, values["R"] * scale, clockwise,
                                            RADIUS_TOLERANCE["mm"])  # the same length in either unit
            except ValueError as exc:
                raise self.fail(lineno, str(exc)) from None
        else:
            if "K" in values:  # LinuxCNC: "K word given for arc in XY plane"
                raise self.fail(lineno, "K is an arc centre word of G18/G19, not of the XY plane (G17)")
            if "I" not in values and "J" not in values:
                raise self.fail(lineno, f"G{self.motion} needs I/J or R")
            ij = np.array([values.get("I", 0.0), values.get("J", 0.0)]) * scale
            centre = ij + self.offset[:2] if self.arc_absolute else self.pos[:2] + ij
            r0 = float(np.hypot(*(self.pos[:2] - centre)))
            r1 = float(np.hypot(*(target[:2] - centre)))
            # LinuxCNC's tolerances, in the program's units: within them the radius is blended (a spiral)
            if problem := centre_arc_problem(r0 / scale, r1 / scale, "inch" if self.inch else "mm"):
                raise self.fail(lineno, problem)
        turns = values.get("P", 1.0)
        if turns != int(turns) or turns < 1:
            raise self.fail(lineno, f"P{turns:g} on an arc must be a whole number of turns >= 1")
        try:
            pts = discretise_arc(self.pos, target, centre, clockwise, self.opt.chord_tolerance, int(turns))
        except ValueError as exc:
            raise self.fail(lineno, str(exc)) from None
        self._emit(pts, Motion.ARC, lineno)

    def _emit(self, pts: np.ndarray, kind: Motion | np.ndarray, lineno: int | np.ndarray) -> None:
        count = len(pts)
        if self.total + count > MAX_POINTS:
            at = MAX_POINTS - self.total
            line = int(lineno if np.isscalar(lineno) else lineno[at])
            raise self.fail(line, f"the program expands to more than {MAX_POINTS:,} points (arcs at a chord "
                                  f"tolerance of {self.opt.chord_tolerance:g} mm included)")
        self.total += count
        self.points.append(pts)
        self.kinds.append(np.broadcast_to(np.int8(kind), (count,)) if np.isscalar(kind) else kind.astype(np.int8))
        self.point_lines.append(np.broadcast_to(np.int32(lineno), (count,)) if np.isscalar(lineno)
                                else lineno.astype(np.int32))

    def run_plain(self, lines: Scan, first: int, stop: int, table: StateTable) -> None:
        """Run plain lines ``first .. stop - 1`` (0-based, :mod:`toolpath.gcode.scanner`) at once: the
        same arithmetic, in the same order, as :meth:`run_block` does line by line."""
        values = lines.values[:, first:stop]
        count = stop - first
        index = np.arange(count)
        g = values[0]
        absent = np.isnan(values[1:4])
        has_axis = ~(absent[0] & absent[1] & absent[2])
        if self.motion not in (0, 1):  # G2/G3 or no motion mode: a line moving before any G0/G1 is an error
            before_g = index < (np.flatnonzero(~np.isnan(g))[0] if (~np.isnan(g)).any() else count)
            if (has_axis & before_g).any():
                bad = first + int(np.flatnonzero(has_axis & before_g)[0])
                body, lineno = self.text[lines.starts[bad]:lines.body_ends[bad]], bad + 1 + self.base
                self.run_block(tokenize(body, self.src, lineno, self.params), lineno)
        last_g = np.maximum.accumulate(np.where(np.isnan(g), -1, index))
        motion = np.where(last_g >= 0, g[np.maximum(last_g, 0)], -1 if self.motion is None else self.motion)
        scale = MM_PER_INCH if self.inch else 1.0
        position = np.empty((3, count))
        for i in range(3):
            v = values[1 + i]
            if self.absolute:
                if not absent[i].any():
                    position[i] = v * scale + self.offset[i]
                elif absent[i].all():
                    position[i] = self.pos[i]
                else:
                    target = v * scale + self.offset[i]
                    last = np.maximum.accumulate(np.where(absent[i], -1, index))
                    position[i] = target[np.maximum(last, 0)]
                    position[i, last < 0] = self.pos[i]
            else:
                steps = np.concatenate([[self.pos[i]], np.where(absent[i], 0.0, v * scale)])
                position[i] = np.add.accumulate(steps)[1:]
        f = values[4] * scale
        last_f = np.maximum.accumulate(np.where(np.isnan(f), -1, index))
        feed = f[np.maximum(last_f, 0)]
        feed[last_f < 0] = np.nan if self.feed is None else self.feed
        moving = np.flatnonzero(has_axis)
        if len(moving):
            kinds = np.where(motion[moving] == 0, Motion.RAPID, Motion.FEED)
            points = position.T if len(moving) == count else position[:, moving].T
            self._emit(np.ascontiguousarray(points), kinds, moving + first + 1 + self.base)
        rows = slice(first + 1, stop + 1)
        table.motion[rows], table.position[rows], table.feed[rows] = motion, position.T, feed
        table.absolute[rows], table.inch[rows] = self.absolute, self.inch
        table.offset_id[rows] = table.offset_index(self.offset)
        table.special[rows] = self.special()  # only a plane other than XY: plain lines never run while stepping
        self.pos = position[:, -1].copy()
        self.motion = None if motion[-1] < 0 else int(motion[-1])
        self.feed = None if np.isnan(feed[-1]) else float(feed[-1])
        self.started = self.started or bool(lines.words[first:stop].any())
