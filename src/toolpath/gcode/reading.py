"""Reading a program in parts: one interpreter carried from part to part, so a program of tens of
millions of lines is read (and smoothed, :mod:`toolpath.smooth.stream`) a few hundred thousand lines
at a time, in bounded memory, with the same numbers as reading it whole.

A part's :class:`~toolpath.gcode.program.Program` numbers its lines from 1 (``lines``, ``states``,
``lines_of_points`` are the part's own) and ``first_line`` says where it sits in the file; errors
name the file's line.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from toolpath.gcode.errors import GCodeError
from toolpath.gcode.interpreter import Interpreter, ReaderOptions
from toolpath.gcode.lexer import tokenize
from toolpath.gcode.passing import grbl_command, integer_word_in
from toolpath.gcode.program import Lines, Program, StateTable
from toolpath.gcode.scanner import scan
from toolpath.gcode.text import MAX_LINE_LENGTH

_UNITS = {frozenset(): "mm (no unit word)", frozenset({"mm"}): "mm", frozenset({"inch"}): "inch"}
_O_WORD = re.compile(r"\s*(?:/\s*)?(?:[nN]\s*\d+\s*)?[oO]")  # an O-word line (a number or control flow)
_COMMENTS = re.compile(r"\([^)]*\)|;.*")


class Reading:
    """An interpreter that reads a program part after part; ``read`` one text, then the next."""

    def __init__(self, source: str = "<string>", options: ReaderOptions | None = None) -> None:
        self.source = source
        self.options = options or ReaderOptions()
        self.interp = Interpreter(source, self.options)
        self.lines_read = 0

    def snapshot(self) -> Reading:
        """A copy that reads on from here: the same modal state, parameters and stored positions."""
        other = copy.copy(self)
        interp = copy.copy(self.interp)
        interp.params = copy.deepcopy(self.interp.params)
        interp.units_seen = set(self.interp.units_seen)
        interp.pos, interp.offset = self.interp.pos.copy(), self.interp.offset.copy()
        interp.unknown, interp.stored = set(self.interp.unknown), dict(self.interp.stored)
        other.interp = interp
        return other

    def with_options(self, options: ReaderOptions) -> Reading:
        """A copy that reads on from here with other options (a coarser chord tolerance, say)."""
        other = self.snapshot()
        other.options = other.interp.opt = options
        return other

    def resume_at(self, state_row: StateTable, row: int, lines_read: int) -> Reading:
        """A copy positioned at ``row`` of ``state_row``: its modal state, this reading's parameters
        (the caller makes sure no parameter, G90.1 / G91.1 or unit changed since that row)."""
        other = self.snapshot()
        state = state_row[row]
        it = other.interp
        it.motion, it.absolute, it.inch, it.feed = state.motion, state.absolute, state.inch, state.feed
        it.pos, it.offset = np.array(state.position), np.array(state.offset)
        other.lines_read = lines_read
        return other

    def _interpret(self, lines, first: int, stop: int) -> None:  # noqa: ANN001 - the text's Scan
        """Lines ``first .. stop - 1`` (0-based in the text) through the interpreter, one by one."""
        interp, base, states = self.interp, self.interp.base, self.interp.table
        for index in range(first, stop):
            if not (interp.ended or interp.stopped):
                body = interp.text[lines.starts[index]:lines.body_ends[index]]
                lineno = base + index + 1
                if len(body) > MAX_LINE_LENGTH:
                    raise GCodeError(self.source, lineno, f"the line is longer than {MAX_LINE_LENGTH} characters")
                if lineno == 1 and body.startswith("\ufeff"):  # a UTF-8 BOM
                    body = body[1:]
                grbl = body.lstrip().startswith(("$", "?", "~", "!")) and grbl_command(_COMMENTS.sub(" ", body))
                if grbl:
                    interp.opaque = False
                    interp.grbl_line(grbl, lineno)
                elif self.options.pass_through and _O_WORD.match(body) and not interp.nurbs:
                    interp.opaque = False
                    interp.o_line(_COMMENTS.sub(" ", body), lineno)
                else:
                    interp.run_block(tokenize(body, self.source, lineno, interp.params), lineno)
            interp.record(states, index + 1)

    def read(self, text: str, vectorise: bool = True, final: bool = True) -> Program:
        """The next part of the program: ``text`` is whole lines (its last may lack an ending only
        at the end of the program).  ``final``: the program ends with it (a G6.2 block still open
        is closed)."""
        interp, base = self.interp, self.lines_read
        interp.points, interp.kinds, interp.point_lines, interp.total = [], [], [], 0
        interp.text, interp.base = text, base
        lines = scan(text)
        count = lines.count
        states = StateTable(count + 1)
        interp.record(states, 0)
        interp.table = states
        plain = lines.fast if vectorise else np.zeros(count, bool)  # '/', '%', comments, '#': never plain
        edges = np.flatnonzero(np.diff(plain.astype(np.int8))) + 1
        bounds = [0, *edges.tolist(), count] if count else [0]
        for first, stop in zip(bounds[:-1], bounds[1:], strict=True):
            if interp.ended or interp.stopped:  # past M2/M30 or the closing '%' a controller reads nothing more
                states.fill(first + 1, count + 1, first)
                break
            while first < stop and plain[first] and interp.stepping():  # one by one until the state is plain
                self._interpret(lines, first, first + 1)
                first += 1
            if first == stop:
                continue
            if plain[first] and interp.nurbs is not None and interp.nurbs.kind == "G5.2":
                self._interpret(lines, first, stop)  # X Y lines are control points until G5.3
                continue
            if plain[first] and interp.nurbs is not None:  # the first line with words ends the G6.2 block
                worded = np.flatnonzero(lines.words[first:stop])
                closing = first + int(worded[0]) + 1 if len(worded) else stop
                self._interpret(lines, first, closing)
                first = closing
                if interp.ended:
                    states.fill(first + 1, count + 1, first)
                    break
            if first < stop and plain[first] and not (interp.ended or interp.stopped):
                increments = self.options.dialect == "fanuc" and not self.options.whole_integer_words
                if increments and (found := integer_word_in(text[lines.starts[first]:lines.starts[stop]])) is not None:
                    raise GCodeError(self.source, base + first + found[0] + 1, found[1])
                interp.run_plain(lines, first, stop, states)
            elif first < stop:
                self._interpret(lines, first, stop)
        if final and interp.nurbs is not None:
            interp.close_nurbs(base + count)
        interp.table = None
        self.lines_read += count
        point_lines = np.concatenate(interp.point_lines) if interp.point_lines else np.zeros(0, np.int32)
        program = Program(
            source=self.source,
            lines=Lines(text, lines.starts),
            points=np.concatenate(interp.points).astype(float) if interp.points else np.zeros((0, 3)),
            kinds=np.concatenate(interp.kinds) if interp.kinds else np.zeros(0, np.int8),
            lines_of_points=(point_lines - base).astype(np.int32),
            units=_UNITS.get(frozenset(interp.units_seen), "mixed inch/mm"),
            states=states,
            plain=plain,
            xy_decimals=lines.decimals,
            first_line=base + 1,
        )
        interp.points, interp.kinds, interp.point_lines = [], [], []
        return program


def text_parts(path: Path, part_bytes: int = 8 << 20) -> Iterator[str]:
    """The file's text in parts of whole lines (each ends with ``\\n`` but the last), about
    ``part_bytes`` each; a run of more than :data:`MAX_LINE_LENGTH` characters without a line end
    stops with a :class:`GCodeError` naming its line.

    Raises
    ------
    OSError
        When the file cannot be opened or read.
    """
    limit = 4 * MAX_LINE_LENGTH  # bytes: UTF-8 takes up to 4 per character
    lines_before, carry = 0, b""
    with path.open("rb") as handle:
        while True:
            chunk = handle.read(part_bytes)
            data = carry + chunk
            if not chunk:
                if data:
                    yield data.decode("utf-8", errors="surrogateescape")
                return
            cut = data.rfind(b"\n") + 1
            if cut == 0:  # lone CRs so far: cut after one, never after the last byte (an LF may follow it)
                cut = data.rfind(b"\r", 0, len(data) - 1) + 1
            _check_line_lengths(path, data, cut, limit, lines_before)
            if cut:
                text = data[:cut].decode("utf-8", errors="surrogateescape")
                lines_before += text.count("\n") + text.count("\r") - text.count("\r\n")
                yield text
            carry = data[cut:]


def _check_line_lengths(path: Path, data: bytes, cut: int, limit: int, lines_before: int) -> None:
    codes = np.frombuffer(data, np.uint8)
    ends = np.flatnonzero((codes == 10) | (codes == 13))
    gaps = np.diff(np.concatenate([[-1], ends, [len(codes)]])) - 1
    if gaps.max(initial=0) > limit:
        k = int(np.argmax(gaps > limit))
        text = data[:ends[k - 1] + 1 if k else 0].decode("utf-8", errors="surrogateescape")
        lineno = lines_before + text.count("\n") + text.count("\r") - text.count("\r\n") + 1
        raise GCodeError(str(path), lineno, f"the line is longer than {MAX_LINE_LENGTH} characters "
                                            "(not a G-code program?)")
