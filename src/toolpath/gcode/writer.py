"""Write G01 programs, and replace the motion of chosen line ranges in an existing program.

The replacement keeps every line outside the ranges byte for byte (line endings included) and
refuses, with an error naming the line, any range holding something it would lose: comments,
M/S/T/H/D words, unit or mode changes, rapids.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from toolpath.gcode.errors import GCodeError
from toolpath.gcode.lexer import tokenize
from toolpath.gcode.reader import MM_PER_INCH, Program

# Words a replacement owns on the lines it rewrites; anything else on those lines is refused.
_OWNED = set("GXYZIJKRFNP")


@dataclass(frozen=True)
class Pass:
    """One closed or open cutting pass: XY points (mm) at one depth ``z``."""

    xy: np.ndarray
    z: float


@dataclass(frozen=True)
class ProgramSpec:
    """Program-level settings of a generated G01 program (all from ``conf/gcode``)."""

    decimals: int = 3
    feed: float = 1200.0
    plunge_feed: float = 300.0
    spindle: float = 12000.0
    safe_z: float = 5.0
    newline: str = "\n"
    stay_down: bool = False  # link passes at one depth by a feed move instead of retract + rapid


def fmt(value: float, decimals: int) -> str:
    """Fixed-point number as CAM posts write it, never ``-0.000``; a NaN or infinity is refused
    (``Xnan`` is not G-code: our reader and every controller refuse it)."""
    if not math.isfinite(value):
        raise ValueError(f"cannot write the non-finite number {value} as G-code")
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def fmt_many(values: np.ndarray, decimals: np.ndarray) -> list[str]:
    """:func:`fmt` of every value with its own decimals, the same strings, in one pass per precision."""
    values, decimals = np.asarray(values, np.float64), np.asarray(decimals, np.int64)
    bad = np.flatnonzero(~np.isfinite(values))
    if len(bad):
        raise ValueError(f"cannot write the non-finite number {values[bad[0]]} as G-code")
    out: list[str] = [""] * len(values)
    for places in np.unique(decimals).tolist():
        where = np.flatnonzero(decimals == places)
        texts = [f"{v:.{places}f}" for v in values[where].tolist()]
        # a negative value that rounds to zero prints as -0.000: fmt drops the sign
        for k in np.flatnonzero((values[where] <= 0) & (values[where] > -(10.0 ** -places))).tolist():
            texts[k] = fmt(float(values[where[k]]), places)
        for index, text in zip(where.tolist(), texts, strict=True):
            out[index] = text
    return out


def g1_moves(points: np.ndarray, decimals: int, first_prefix: str = "G1") -> list[str]:
    """``G1`` lines through ``points`` (k, 2|3), omitting axis words that do not change (modal)."""
    out, last = [], [None, None, None]
    for k, p in enumerate(points):
        words = []
        for i, axis in enumerate("XYZ"[: points.shape[1]]):
            text = fmt(float(p[i]), decimals)
            if text != last[i]:
                words.append(f"{axis}{text}")
                last[i] = text
        if words:
            out.append(" ".join(([first_prefix] if k == 0 else []) + words))
    return out


def write_program(passes: Sequence[Pass], spec: ProgramSpec, title: str = "") -> str:
    """A complete metric G01 program cutting ``passes`` in order, retracting between them.

    The structure is that of a CAM post: header, units and modes, spindle on, then per pass a
    retract, rapid to the start, plunge at the plunge feed and the contour at the cutting feed.
    """
    d, nl = spec.decimals, spec.newline
    lines = [f"({title})" if title else "(toolpath-lab)", "G21 G90 G17 G40 G49 G80",
             f"S{fmt(spec.spindle, 0)} M3"]
    for k, cut in enumerate(passes):
        x0, y0 = cut.xy[0]
        lines.append(f"(pass {k + 1} of {len(passes)}, Z{fmt(cut.z, d)})")
        linked = spec.stay_down and k > 0 and cut.z == passes[k - 1].z
        if linked:  # CAM "stay down" link: a feed move to the next pass at the same depth
            lines.append(f"G1 X{fmt(x0, d)} Y{fmt(y0, d)}")
        else:
            lines.append(f"G0 Z{fmt(spec.safe_z, d)}")
            lines.append(f"G0 X{fmt(x0, d)} Y{fmt(y0, d)}")
            lines.append(f"G1 Z{fmt(cut.z, d)} F{fmt(spec.plunge_feed, 0)}")
        moves = g1_moves(np.asarray(cut.xy[1:]), d)
        if moves and not linked:
            moves[0] += f" F{fmt(spec.feed, 0)}"
        lines.extend(moves)
    lines += [f"G0 Z{fmt(spec.safe_z, d)}", "M5", "M30"]
    return nl.join(lines) + nl


def _check_range(program: Program, first: int, last: int) -> bool:
    """Refuse a range holding anything but feed motion; return whether it carries an F word."""
    has_feed = False
    for lineno in range(first, last + 1):
        raw = program.lines[lineno - 1].rstrip("\r\n")
        if "(" in raw or ";" in raw:
            raise GCodeError(program.source, lineno, "the range to replace holds a comment, which would be lost")
        block = tokenize(raw, program.source, lineno)
        if block.percent or block.block_delete:
            raise GCodeError(program.source, lineno, "the range to replace holds a '%' or '/' line")
        for w in block.words:
            if w.letter not in _OWNED or (w.letter == "G" and w.value not in (1.0, 2.0, 3.0)):
                raise GCodeError(program.source, lineno,
                                 f"the range to replace holds {w.letter}{w.text}, which it does not own")
            has_feed |= w.letter == "F"
    return has_feed


def _check_next_line(program: Program, last: int) -> None:
    """The line after a range must not rely on a modal G2/G3 that the new G1 lines would change."""
    if program.states[last].motion in (None, 1):
        return
    for lineno in range(last + 1, len(program.lines) + 1):
        block = tokenize(program.lines[lineno - 1].rstrip("\r\n"), program.source, lineno)
        letters = {w.letter for w in block.words}
        if letters & set("XYZ"):
            if not any(w.letter == "G" and w.value in (0.0, 1.0, 2.0, 3.0) for w in block.words):
                raise GCodeError(program.source, lineno,
                                 f"relies on modal G{program.states[last].motion}; extend the range over it")
            return
        if any(w.letter == "G" and w.value in (0.0, 1.0, 2.0, 3.0) for w in block.words):
            return


def replace_motion(program: Program, replacements: Sequence[tuple[int, int, np.ndarray]],
                   decimals: int = 3) -> str:
    """Text of ``program`` with lines ``first..last`` (1-based, inclusive) replaced by G1 moves.

    Each replacement's points (k, 2|3) are in mm in the reader's frame and must end where the
    original range ends (within half a unit of the last written decimal), so every later line
    keeps its meaning.  New lines follow the program's state at that place: inch programs are
    written in inch with one more decimal, G91 programs incrementally (rounded cumulatively, so
    no drift), G92 offsets are honoured, the first new line carries the range's last F word.
    N words inside a range are dropped with the motion they numbered.

    Raises
    ------
    GCodeError
        When a range holds words it does not own, or the next line would change meaning.
    ValueError
        For overlapping or out-of-range line numbers or a replacement that does not end where
        the original range ends.
    """
    out = list(program.lines)
    previous_last = 0
    for first, last, pts in sorted(replacements, key=lambda r: r[0]):
        if not 1 <= first <= last <= len(program.lines) or first <= previous_last:
            raise ValueError(f"line range {first}..{last} is out of bounds or overlaps another")
        previous_last = last
        has_feed = _check_range(program, first, last)
        _check_next_line(program, last)
        before, after = program.states[first - 1], program.states[last]
        pts = np.asarray(pts, dtype=float)
        if not np.isfinite(pts).all():
            raise GCodeError(program.source, first, f"the replacement for lines {first}..{last} holds a non-finite "
                                                    "point; nothing was written")
        if pts.shape[1] == 2:
            pts = np.column_stack([pts, np.full(len(pts), after.position[2])])
        scale = MM_PER_INCH if before.inch else 1.0
        d = decimals + 1 if before.inch else decimals
        if np.max(np.abs(pts[-1] - np.array(after.position))) > 0.5 * 10.0**-d * scale + 1e-9:
            raise ValueError(f"replacement for lines {first}..{last} ends at {pts[-1]}, "
                             f"not at the original end {after.position}")
        prog = (pts - np.array(before.offset)) / scale  # program coordinates, program units
        rounded = np.round(prog, d)
        if not before.absolute:
            start = np.round((np.array(before.position) - np.array(before.offset)) / scale, d)
            rounded = np.diff(np.vstack([start, rounded]), axis=0)
        lines = g1_moves(rounded, d) if before.absolute else _incremental_moves(rounded, d)
        if has_feed and after.feed is not None and lines:
            lines[0] += f" F{fmt(after.feed / scale, max(d - 2, 0))}"
        original = program.lines[first - 1]
        ending = original[len(original.rstrip("\r\n")):] or "\n"  # CRLF, LF or a lone CR, as the line had
        out[first - 1] = "".join(line + ending for line in lines)
        for k in range(first, last):
            out[k] = ""
    return "".join(out)


def _incremental_moves(deltas: np.ndarray, decimals: int) -> list[str]:
    """``G1`` lines of incremental moves, skipping axes that do not move."""
    out = []
    for k, p in enumerate(deltas):
        words = [f"{a}{fmt(float(v), decimals)}" for a, v in zip("XYZ", p, strict=False)
                 if fmt(float(v), decimals) not in (fmt(0.0, decimals),)]
        if words:
            out.append(" ".join((["G1"] if k == 0 else []) + words))
    return out
