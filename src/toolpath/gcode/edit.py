"""Change the X/Y numbers of single G1 lines in place, leaving every other character of the line alone.

``toolpath smooth`` moves points, never adds or removes them: each moved point is the end point of
exactly one ``G1`` line, so the rewrite is a substitution of that line's X and Y numbers.  N words,
F/S/T/M words, comments, spacing, letter case and the line ending stay as they were.  Which lines
qualify is :func:`movable_lines`; everything else is kept byte for byte by construction.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from toolpath.gcode.lexer import tokenize
from toolpath.gcode.reader import MM_PER_INCH, Motion, Program

# a plain number as the lexer reads it (blanks allowed after the letter and around the sign)
_PLAIN = re.compile(r"\s*[+-]?\s*(\d+\.?\d*|\.\d+)")
_AXIS_LETTER = re.compile(r"[XxYy]")
_NUMBER = r"\s*[+-]?\s*(?:\d+\.?\d*|\.\d+)"
_AXIS_WORD = re.compile(rf"([XxYy]){_NUMBER}")
_X_THEN_Y = re.compile(rf"([^XxYy]*[Xx]){_NUMBER}([^XxYy]*[Yy]){_NUMBER}")  # the usual order, in one match


@dataclass(frozen=True)
class AxisWord:
    """Where an axis word's number sits in a line: ``line[start:end]`` is ``X-1.250`` (letter included)."""

    start: int
    end: int
    decimals: int


def _code_spans(line: str) -> list[tuple[int, int]]:
    """Spans of ``line`` outside ``( )`` and ``;`` comments."""
    spans, start, i = [], 0, 0
    while i < len(line):
        ch = line[i]
        if ch == ";":
            spans.append((start, i))
            return spans
        if ch == "(":
            spans.append((start, i))
            close = line.find(")", i + 1)
            i = len(line) if close < 0 else close + 1
            start = i
            continue
        i += 1
    spans.append((start, len(line)))
    return spans


def axis_words(line: str) -> dict[str, AxisWord]:
    """The X and Y words of a line whose numbers are plain (not ``#`` parameters or expressions)."""
    found: dict[str, AxisWord] = {}
    spans = _code_spans(line) if "(" in line or ";" in line else [(0, len(line))]
    if any(c in line[lo:hi] for lo, hi in spans for c in "#["):
        return {}  # values computed from parameters: the line is not ours to rewrite
    for lo, hi in spans:
        for letter in _AXIS_LETTER.finditer(line, lo, hi):
            i = letter.start()
            match = _PLAIN.match(line, i + 1, hi)
            if match is None:
                return {}  # X#1, X[...]: not a number we can rewrite
            digits = match.group(1)
            found[letter.group().upper()] = AxisWord(i, match.end(), len(digits.split(".")[1]) if "." in digits else 0)
    return found


def movable_lines(program: Program) -> np.ndarray:
    """Per line (index 0 = line 1): True when the line is one straight feed move whose X/Y numbers can
    be substituted without changing anything else it does.

    That is: it reaches exactly one point, by G1, in the XY plane at the Z it started from; its X and
    Y numbers (where present) are plain numbers; and it holds no word that acts beyond the move
    (G other than 1, M, S, T, H, D, P, R, I/J/K).  An F word stays on the line with its value.
    """
    counts = np.bincount(program.lines_of_points, minlength=len(program.lines) + 1)[1:]
    last_kind = np.full(len(program.lines) + 1, -1)
    last_kind[program.lines_of_points] = program.kinds
    z = program.states.position[:, 2]
    ok = (counts == 1) & (last_kind[1:] == Motion.FEED) & (z[1:] == z[:-1])  # a ramp: its XY is not all it does
    plain = program.plain if program.plain is not None else np.zeros(len(ok), bool)
    # a plain line (G0/G1 X Y Z F N, plain numbers) that feeds to one point qualifies as it is
    for index in np.flatnonzero(ok & ~plain):
        lineno = index + 1
        raw = program.lines[index].rstrip("\r\n")
        if any(c in raw[lo:hi] for lo, hi in _code_spans(raw) for c in "#["):
            ok[index] = False  # X/Y/Z or F from parameters: substituting a number would cut the link
            continue
        words = tokenize(raw, program.source, lineno).words
        if any(w.letter not in "GXYZNF" or (w.letter == "G" and w.value != 1.0) for w in words):
            ok[index] = False
            continue
        letters = {w.letter for w in words}
        if len(axis_words(raw)) != len(letters & set("XY")):
            ok[index] = False
    return ok


def substitute_xy(line: str, values: dict[str, str]) -> str:
    """``line`` with the numbers of its X/Y words replaced by ``values`` (letter -> number text).

    A word the line lacks (modal) is inserted: X before the Y word, Y after the X word, or at the end
    of the code before any comment; the line's ending is kept.
    """
    body = line.rstrip("\r\n")
    ending = line[len(body):]
    words = axis_words(body)
    edits: list[tuple[int, int, str]] = []
    for letter, number in values.items():
        if letter in words:
            w = words[letter]
            case = body[w.start]
            edits.append((w.start, w.end, f"{case}{number}"))
    missing = [letter for letter in values if letter not in words]
    for letter in missing:
        text = f"{letter}{values[letter]}"
        if letter == "X" and "Y" in words:
            edits.append((words["Y"].start, words["Y"].start, text + " "))
        elif letter == "Y" and "X" in words:
            end = words["X"].end
            edits.append((end, end, " " + text))
        else:
            code_end = _code_spans(body)[0][1]
            while code_end > 0 and body[code_end - 1].isspace():
                code_end -= 1
            edits.append((code_end, code_end, " " + text))
    for start, end, text in sorted(edits, key=lambda e: (e[0], e[1]), reverse=True):
        body = body[:start] + text + body[end:]
    return body + ending


def substitute_plain_xy(line: str, x: str, y: str) -> str:
    """:func:`substitute_xy` of both X and Y on a line the scanner found plain (no comment, no parameter,
    each letter once), in one regular-expression pass; a line lacking X or Y takes the general route."""
    usual = _X_THEN_Y.match(line)
    if usual is not None:
        return f"{usual.group(1)}{x}{usual.group(2)}{y}{line[usual.end():]}"
    letters = []

    def put(match: re.Match) -> str:
        letters.append(match.group(1))
        return match.group(1) + (x if match.group(1) in "Xx" else y)

    out = _AXIS_WORD.sub(put, line)
    if len(letters) == 2 and letters[0].upper() != letters[1].upper():
        return out
    return substitute_xy(line, {"X": x, "Y": y})


def program_coordinates(program: Program, lineno, xy_mm: np.ndarray) -> np.ndarray:  # noqa: ANN001 - int or array
    """A point (mm, reader frame) as the X/Y numbers line ``lineno`` would write in absolute mode; or many
    points (k, 2), one per line of the array ``lineno``."""
    row = np.asarray(lineno, np.int64) - 1
    scale = np.where(program.states.inch[row], MM_PER_INCH, 1.0)
    offset = np.asarray(program.states.offsets)[program.states.offset_id[row]][..., :2]
    return (np.asarray(xy_mm, float) - offset) / scale[..., None]
