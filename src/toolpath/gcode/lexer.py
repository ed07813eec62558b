"""Split one RS-274 line into words (parameters and expressions evaluated).  Used by :mod:`toolpath.gcode.reader`.

Handles what CAM systems really write: compact words (``G1X1.5Y-2``), lowercase, zero-padded
numbers (``G01``), spaces between a letter and its number, ``( )`` and ``;`` comments (also after
words), ``%`` delimiters and block delete ``/``.  Features the reader does not implement are
rejected here with a :class:`GCodeError` rather than skipped.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from toolpath.gcode.errors import GCodeError
from toolpath.gcode.expressions import ExpressionError, Parameters, Scanner

# A word is a letter and a real number; LinuxCNC also allows blanks between sign and digits.
_NUMBER = re.compile(r"\s*([+-]?)\s*(\d+\.?\d*|\.\d+)")
# the interpreter decides on A B C U V W (axes it does not follow), E (an M66-M68 channel) and LinuxCNC's
# polar words @ (distance) and ^ (angle); $ selects a spindle (LinuxCNC)
_KNOWN_LETTERS = set("GMNFSTHDXYZIJKRPQLABCUVWE@^$")
# The largest magnitude a word may have: 1e9 (a kilometre in micrometres, a million in any feed or speed);
# past it a number is a typo or an attack, and 1e400 would be infinity.
MAX_WORD_VALUE = 1.0e9
_FUNCTION_CALL = re.compile(r"(ABS|ACOS|ASIN|ATAN|COS|EXISTS|EXP|FIX|FUP|ROUND|LN|SIN|SQRT|TAN)\s*\[", re.IGNORECASE)


@dataclass(frozen=True, slots=True)
class Word:
    """One ``letter value`` pair; ``text`` keeps the number as written (``"01"``, ``"-.5"``)."""

    letter: str
    text: str
    value: float


@dataclass(frozen=True, slots=True)
class Block:
    """The words of one line, plus whether it is a ``%`` delimiter or block-deleted."""

    words: tuple[Word, ...]
    percent: bool = False
    block_delete: bool = False
    assignments: tuple[tuple[int | str, float], ...] = ()  # to apply when the line runs (after all its values)


def _strip_comments(body: str, source: str, lineno: int) -> str:
    """Remove ``( )`` comments and everything after ``;``; an unclosed ``(`` is an error."""
    out: list[str] = []
    i = 0
    while i < len(body):
        ch = body[i]
        if ch == ";":
            break
        if ch == "(":
            close = body.find(")", i + 1)
            if close < 0:
                raise GCodeError(source, lineno, "comment opened with '(' is never closed")
            out.append(" ")  # a comment separates words like a blank does
            i = close + 1
            continue
        if ch == ")":
            raise GCodeError(source, lineno, "')' without a matching '('")
        out.append(ch)
        i += 1
    return "".join(out)


def tokenize(line: str, source: str = "<string>", lineno: int = 0, params: Parameters | None = None) -> Block:
    """Split one line (without its line ending) into a :class:`Block`.

    With ``params`` (the reader's parameter table), ``#`` parameters, assignments and ``[ ]``
    expressions are evaluated (:mod:`toolpath.gcode.expressions`); the line's assignments are
    returned in the block, for the reader to apply if the line runs.  Without, they are refused.

    Raises
    ------
    GCodeError
        For malformed words and for features the reader does not support: ``#`` parameters and
        ``[ ]`` expressions without ``params``, O-word control flow.
    """
    stripped = line.strip()
    if stripped.startswith("%"):
        return Block(words=(), percent=True)
    deleted = stripped.startswith("/")
    body = _strip_comments(stripped[1:] if deleted else stripped, source, lineno)
    if not body.isascii():  # Python's digits and blanks include Arabic-Indic digits and a no-break space
        column, ch = next((k, c) for k, c in enumerate(body) if not c.isascii())
        raise GCodeError(source, lineno, f"character {ch!r} (U+{ord(ch):04X}) outside a comment: a control reads "
                                         "a line's words in ASCII only")
    words: list[Word] = []
    assignments: list[tuple[int | str, float]] = []
    i, n = 0, len(body)
    while i < n:
        ch = body[i]
        if ch.isspace():
            i += 1
            continue
        if ch == "#":
            if params is None:
                raise GCodeError(source, lineno, "'#' parameters and expressions are not supported")
            i = _assignment(body, i, params, assignments, source, lineno)
            continue
        if ch in "[]":
            raise GCodeError(source, lineno, "an expression '[ ]' must follow a word letter or '='")
        upper = ch.upper()
        if upper == "O":
            raise GCodeError(source, lineno, "O-word control flow (subroutines, loops) is not supported")
        if not ch.isalpha() and ch not in "@^$":
            raise GCodeError(source, lineno, f"unexpected character {ch!r}")
        if upper == "E" and words and body[i - 1 : i].isdigit() and _NUMBER.match(body, i + 1) is not None:
            raise GCodeError(source, lineno, f"{words[-1].letter}{words[-1].text}{body[i:match_end(body, i + 1)]}: "
                                             "exponent notation is not G-code (a number is digits with one '.')")
        if upper not in _KNOWN_LETTERS:
            raise GCodeError(source, lineno, f"unknown word letter {upper!r}")
        match = _NUMBER.match(body, i + 1)
        if match is None and params is not None and _starts_value(body, i + 1):
            scanner = Scanner(body, params, i + 1)
            try:
                value = scanner.value()
            except ExpressionError as exc:
                raise GCodeError(source, lineno, f"word {upper}: {exc}") from None
            words.append(_checked(Word(upper, body[i + 1 : scanner.pos].strip(), value), source, lineno))
            i = scanner.pos
            continue
        if match is None:
            following = body[i + 1 : i + 2]
            if following == "#":
                raise GCodeError(source, lineno, "'#' parameters and expressions are not supported")
            if following == "[":
                raise GCodeError(source, lineno, "'[ ]' expressions are not supported")
            raise GCodeError(source, lineno, f"word {upper} has no number")
        text = match.group(1) + match.group(2)
        words.append(_checked(Word(upper, text, float(text)), source, lineno))
        i = match.end()
    return Block(words=tuple(words), block_delete=deleted, assignments=tuple(assignments))


def match_end(body: str, pos: int) -> int:
    """Where the number starting at ``pos`` ends (``pos`` if none does)."""
    match = _NUMBER.match(body, pos)
    return match.end() if match else pos


def _checked(word: Word, source: str, lineno: int) -> Word:
    """The word, or a :class:`GCodeError` when its value is past :data:`MAX_WORD_VALUE` (or not finite)."""
    if not abs(word.value) <= MAX_WORD_VALUE:
        raise GCodeError(source, lineno, f"word {word.letter}{word.text[:20]}{'...' if len(word.text) > 20 else ''} "
                                         f"is out of range (the largest magnitude read is {MAX_WORD_VALUE:g})")
    return word


def _starts_value(body: str, pos: int) -> bool:
    """Whether a word's value at ``pos`` is a parameter, expression or function rather than missing."""
    rest = body[pos:].lstrip(" \t")
    return bool(rest) and (rest[0] in "#[+-" or _FUNCTION_CALL.match(rest) is not None)


def _assignment(body: str, pos: int, params: Parameters, out: list, source: str, lineno: int) -> int:
    """``#key = value`` at ``pos``: evaluate now (with the parameters as before the line), record it."""
    scanner = Scanner(body, params, pos)
    try:
        key = scanner.parameter_key()
        scanner._skip()
        if not body.startswith("=", scanner.pos):
            raise ExpressionError("a parameter outside a word must be set with '='")
        scanner.pos += 1
        value = scanner.value()
        if not abs(value) <= MAX_WORD_VALUE:
            name = f"#<{key}>" if isinstance(key, str) else f"#{key}"
            raise ExpressionError(f"{name} = {value:g} is out of range (the largest magnitude read is "
                                  f"{MAX_WORD_VALUE:g})")
        out.append((key, value))
    except ExpressionError as exc:
        raise GCodeError(source, lineno, str(exc)) from None
    return scanner.pos
