"""A vectorised scan of a whole program: where its lines are, and the words of every line that is
one of the plain motion lines CAM posts write by the million (``N120 G1 X12.5 Y-3.25 Z0.1 F1200``).

Reading a program line by line in Python is bounded at about 50,000 lines/s (one tokenizer call,
one dictionary, one interpreter step per line).  Most lines of a real milling program use only
the letters G, X, Y, Z, F and N with plain numbers, so this module scans the whole text at once
with NumPy: it finds the line ends, classifies every character, cuts the numbers out, parses them
exactly and marks each line *fast* when it is such a plain line.  The reader runs the fast lines
in vectorised runs and every other line (comments, parameters, arcs, modes, anything malformed)
through the full interpreter, which also gives the exact error of a bad line.

A fast line: characters only from ``GXYZFN`` (either case), digits, ``.``, ``+``, ``-``, blanks
and tabs; every letter immediately followed by a number ``[+-]digits[.digits]`` (at most 15
digits, magnitude at most :data:`~toolpath.gcode.lexer.MAX_WORD_VALUE`); every number preceded
by its letter; each letter at most once; a G word only G0 or G1; at most
:data:`~toolpath.gcode.text.MAX_LINE_LENGTH` characters.  Blank lines are fast too.

Numbers are parsed as ``mantissa / 10**decimals`` with an integer mantissa of at most 15 digits:
both are exact doubles and IEEE division rounds correctly, so every value is bit-identical to
``float(text)`` (a test checks this against the full lexer).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolpath.gcode.lexer import MAX_WORD_VALUE
from toolpath.gcode.text import MAX_LINE_LENGTH

#: column of each letter in :attr:`Scan.values`
LETTERS = "GXYZFN"
_OTHER, _DIGIT, _DOT, _SIGN, _BLANK, _LETTER, _END = range(7)
_CLASS = np.full(256, _OTHER, np.int8)
_CLASS[np.frombuffer(b"0123456789", np.uint8)] = _DIGIT
_CLASS[ord(".")] = _DOT
_CLASS[[ord("+"), ord("-")]] = _SIGN
_CLASS[[ord(" "), ord("\t")]] = _BLANK
_CLASS[np.frombuffer((LETTERS + LETTERS.lower()).encode(), np.uint8)] = _LETTER
_CLASS[[10, 13]] = _END
_COLUMN = np.full(256, -1, np.int8)
for _i, _c in enumerate(LETTERS):
    _COLUMN[ord(_c)] = _COLUMN[ord(_c.lower())] = _i
_POW10 = 10.0 ** np.arange(16)
MAX_DIGITS = 15  # an integer of 15 digits is an exact double
BLOCK_CHARS = 1 << 18  # scan this many characters at a time: bounds the temporary arrays (~60 MB)


@dataclass
class Scan:
    """The lines of a text and the words of its fast lines.

    ``starts[k]`` is where line k (0-based) starts, ``starts[n]`` the text's length; ``body_ends[k]``
    where its body ends (before ``\\n``, ``\\r\\n`` or a lone ``\\r``).  ``values[c, k]`` is the
    number of letter ``LETTERS[c]`` on fast line k (NaN: absent); ``decimals[k, 0|1]``
    the digits after the point of its X / Y number (-1: absent); ``words[k]`` whether the line has any word.
    """

    starts: np.ndarray
    body_ends: np.ndarray
    fast: np.ndarray
    values: np.ndarray
    decimals: np.ndarray
    words: np.ndarray

    @property
    def count(self) -> int:
        return len(self.body_ends)


def codes_of(text: str) -> np.ndarray:
    """One integer per character: bytes for an ASCII text, UTF-32 code points otherwise (so an index
    into the array is an index into the string)."""
    if text.isascii():
        return np.frombuffer(text.encode("ascii"), np.uint8)
    return np.frombuffer(text.encode("utf-32-le", errors="surrogatepass"), np.uint32)


def line_bounds(codes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(starts with the total length appended, body ends) of the lines, split as controllers do:
    at LF, CRLF and a lone CR; a last line without an ending counts."""
    newline = codes == 10
    if not (codes == 13).any():
        ends = np.flatnonzero(newline)
        body_ends = ends
    else:
        cr = codes == 13
        lone_cr = cr.copy()
        lone_cr[:-1] &= ~newline[1:]
        ends = np.flatnonzero(newline | lone_cr)
        crlf = newline[ends] & (ends > 0) & cr[np.maximum(ends - 1, 0)]
        body_ends = ends - crlf
    starts = np.concatenate([[0], ends + 1]).astype(np.int64)
    body_ends = body_ends.astype(np.int64)
    if starts[-1] < len(codes):  # a last line without its ending
        body_ends = np.append(body_ends, len(codes))
        starts = np.append(starts, len(codes))
    return starts, body_ends


def scan(text: str) -> Scan:
    """Lines and fast-line words of ``text`` (see the module docstring)."""
    codes = codes_of(text)
    starts, body_ends = line_bounds(codes)
    n = len(body_ends)
    values = np.full((len(LETTERS), n), np.nan)
    decimals = np.full((n, 2), -1, np.int8)
    fast = (body_ends - starts[:-1]) <= MAX_LINE_LENGTH
    words = np.zeros(n, bool)
    first = 0
    while first < n:  # blocks of whole lines
        last = int(np.searchsorted(starts, starts[first] + BLOCK_CHARS, side="right")) - 1
        last = min(max(last, first + 1), n)
        lo, hi = int(starts[first]), int(starts[last])
        _scan_block(codes[lo:hi], starts[first:last + 1] - lo, first, values, decimals, fast, words)
        first = last
    return Scan(starts, body_ends, fast, values, decimals, words)


def _scan_block(codes: np.ndarray, starts: np.ndarray, first: int, values: np.ndarray, decimals: np.ndarray,
                fast: np.ndarray, words: np.ndarray) -> None:
    """Scan the lines ``first ..`` whose characters are ``codes`` (``starts`` relative to it)."""
    if codes.dtype == np.uint8:
        cls = _CLASS[codes]
    else:
        cls = np.where(codes < 256, _CLASS[np.minimum(codes, 255)], _OTHER).astype(np.int8)
    slow: list[np.ndarray] = []

    def line_of(positions: np.ndarray) -> np.ndarray:
        return np.searchsorted(starts, positions, side="right") - 1

    slow.append(line_of(np.flatnonzero(cls == _OTHER)))
    numeric = (cls >= _DIGIT) & (cls <= _SIGN)
    begins = numeric.copy()
    begins[1:] &= ~numeric[:-1]
    token_starts = np.flatnonzero(begins)
    closes = numeric.copy()
    closes[:-1] &= ~numeric[1:]
    token_ends = np.flatnonzero(closes) + 1
    letters = np.flatnonzero(cls == _LETTER)
    # a letter must be followed by its number, a number preceded by its letter, a sign start a number
    follows = letters + 1
    lonely = letters[(follows >= len(codes)) | ~numeric[np.minimum(follows, len(codes) - 1)]]
    slow.append(line_of(lonely))
    letter_at = token_starts - 1
    orphan = (letter_at < 0) | (cls[np.maximum(letter_at, 0)] != _LETTER)
    slow.append(line_of(token_starts[orphan]))
    per_line = np.add.reduceat(begins, starts[:-1], dtype=np.int64) if len(codes) else np.zeros(len(starts) - 1, int)
    per_line[starts[:-1] == starts[1:]] = 0  # reduceat gives an empty line the next line's first element
    token_lines = np.repeat(np.arange(len(starts) - 1), per_line)
    number, fraction, bad = _numbers(codes, token_starts, token_ends)
    slow.append(token_lines[bad])
    slow.append(token_lines[np.abs(number) > MAX_WORD_VALUE])
    column = _COLUMN[codes[np.maximum(letter_at, 0)].astype(np.int64) & 255] if len(number) else np.zeros(0, np.int8)
    column = np.where(orphan, 0, column).astype(np.int64)
    seen = np.bincount(token_lines * len(LETTERS) + column, minlength=(len(starts) - 1) * len(LETTERS))
    slow.append(np.flatnonzero(seen > 1) // len(LETTERS))
    slow.append(token_lines[(column == 0) & (number != 0.0) & (number != 1.0)])
    rows = token_lines + first
    values[column, rows] = number
    for axis, col in ((0, 1), (1, 2)):
        pick = column == col
        decimals[rows[pick], axis] = fraction[pick]
    words[rows] = True
    slow_lines = np.concatenate(slow) + first
    fast[slow_lines] = False
    values[:, slow_lines] = np.nan
    decimals[slow_lines] = -1


def _numbers(codes: np.ndarray, token_starts: np.ndarray, token_ends: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The value of every number ``codes[token_starts[i]:token_ends[i]]`` (runs of digits, '.', '+', '-'),
    its digits after the point, and whether it is not a plain ``[+-]digits[.digits]`` of at most 15 digits.

    Horner's scheme column by column: the mantissa stays an exact integer below 2**53."""
    length = token_ends - token_starts
    width = int(min(length.max(initial=0), MAX_DIGITS + 3))
    padded = np.concatenate([codes, np.zeros(width, codes.dtype)])
    mantissa = np.zeros(len(token_starts), np.int64)
    digits = np.zeros(len(token_starts), np.int16)
    fraction = np.zeros(len(token_starts), np.int16)
    dots = np.zeros(len(token_starts), np.int16)
    bad = length > MAX_DIGITS + 2
    for j in range(width):
        c = padded[token_starts + j].astype(np.int16)
        inside = j < length
        digit = c - 48
        is_digit = inside & (digit >= 0) & (digit <= 9)
        mantissa += is_digit * (mantissa * 9 + digit)  # x 10 + digit where a digit, else unchanged
        digits += is_digit
        dots += inside & (c == 46)
        fraction += is_digit & (dots > 0)
        if j:
            bad |= inside & ((c == 43) | (c == 45))  # a sign inside a number
    bad |= (dots > 1) | (digits < 1) | (digits > MAX_DIGITS)
    mantissa = np.where(bad, 0, mantissa).astype(np.float64)  # exact below 2**53: at most 15 digits
    number = mantissa / _POW10[np.minimum(fraction, MAX_DIGITS)]
    number = np.where(codes[token_starts] == ord("-"), -number, number) if len(token_starts) else number
    return number, np.minimum(fraction, 127).astype(np.int8), bad
