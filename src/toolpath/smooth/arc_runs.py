"""Which runs of a program's lines ``toolpath smooth --arcs`` may replace by an arc
(:mod:`toolpath.smooth.arc_weld`), found from the program's columns and one scan of its text: plain G1 moves
in absolute mode, bare of comments and block delete, one feed, where the tool stands the same with the
block-delete switch on or off."""

from __future__ import annotations

import re

import numpy as np

from toolpath.gcode.edit import movable_lines
from toolpath.gcode.lexer import tokenize
from toolpath.gcode.program import Lines, Program
from toolpath.geometry.labels.windows import feed_runs

MOTION_CODES = {0.0, 1.0, 2.0, 3.0, 5.0, 5.1, 5.2, 33.0, 33.1, 73.0, 76.0}  # with G38.x and G80-G89
_INVERSE_TIME = re.compile(r"G[^\S\r\n]*0*93(?![\d.])", re.IGNORECASE)  # within a line (see occurs)
# a line an arc may replace holds no block delete and no comment: a ``/`` line runs or not by the switch; a
# comment may be a MSG or DEBUG the operator sees
_NOT_BARE = "/(;"
_LETTER_F = "Ff"


def weldable_runs(program: Program,
                  stable: np.ndarray | None = None) -> list[tuple[np.ndarray, np.ndarray, int, int, bool]]:
    """Per feed run, maximal point ranges ``i..e`` whose lines ``L(i+1)..L(e)`` are plain G1 lines in absolute
    mode, consecutive from ``L(i+1)`` on (lines before it that leave X and Y where they are, a plunge, stay),
    with no block delete or comment, an F word only on the first (or one repeating the feed in effect), none
    read past blind (:mod:`toolpath.gcode.passing`), and (``stable``) where the tool stands before and after
    each the same with the block-delete switch on or off: (xy, lines, i, e, whether an arc may end at ``e``:
    the line after ``L(e)`` sets its own motion mode, so it cannot inherit the arc's, or is a bare G1 line
    that moves nowhere, which may be given a ``G1``)."""
    count = len(program.lines)
    movable = movable_lines(program) & ~lines_holding(program, _NOT_BARE)[1:]
    stable = np.ones(count + 1, bool) if stable is None else stable
    stable = stable & ~program.states.blind  # where the reader read past a construct: never welded
    # an F word that repeats the feed in effect changes nothing a controller does (ArcWelder drops it too),
    # except in inverse time (G93), where F is each move's own time
    inverse_time = occurs(program, _INVERSE_TIME)
    feed, absolute = program.states.feed, program.states.absolute
    feeds = feed_lines(program, movable)
    new_feed = feeds.copy()  # index = line
    if not inverse_time:
        new_feed[1:] &= feed[1:] != feed[:-1]
    # per line (index = line): a plain G1 move in absolute mode, where the tool stands the same either way
    plain = np.zeros(count + 1, bool)
    plain[1:] = movable & absolute[1:] & stable[1:]
    # lines between two points are plain G1 moves to where the tool stands (a CAM's repeated corner): an arc
    # passes over them as over the lines it replaces; ``blocking[:k]`` counts the lines up to k that may not
    blocking = np.concatenate([[0], np.cumsum(~(plain & ~feeds))])
    out = []
    for xy, lines in feed_runs(program):
        lines = lines.astype(np.int64)
        replaceable, joined = np.zeros(len(lines), bool), np.zeros(len(lines), bool)
        replaceable[1:] = plain[lines[1:]] & stable[lines[1:] - 1]
        # no blocking line strictly between (two points of one line: none between)
        joined[1:] = (lines[1:] <= lines[:-1] + 1) | (blocking[lines[1:]] == blocking[lines[:-1] + 1])
        extends = replaceable & joined & ~new_feed[lines]
        k = 1
        while k < len(lines):
            if not replaceable[k]:
                k += 1
                continue
            i, k = k - 1, k + 1
            while k < len(lines) and extends[k]:
                k += 1
            after = int(lines[k - 1]) + 1
            # a bare plain G1 line after it (one that moves nowhere, so in no run) takes a written G1 as well
            out.append((xy, lines, i, k - 1, after > count or sets_motion(program, after)
                        or (bool(movable[after - 1]) and bool(absolute[after]))))
    return out


def text_of(program: Program) -> str:
    lines = program.lines
    return lines.text if isinstance(lines, Lines) else "".join(lines)


def edited(program: Program, edits: dict[int, str], removed: list[tuple[int, int]] = ()) -> str:
    """The program's text with line ``k`` replaced by ``edits[k]`` and the lines ``first..last`` of each
    ``removed`` range left out (a piece of text per edit or range, not per line)."""
    lines = program.lines
    if not isinstance(lines, Lines):
        gone = {k for a, b in removed for k in range(a, b + 1)}
        return "".join(edits.get(n, "" if n in gone else raw) for n, raw in enumerate(lines, start=1))
    text, starts = lines.text, lines.starts
    pieces = sorted([(k, k, edits[k]) for k in edits] + [(a, b, "") for a, b in removed])
    out, at = [], 0
    for first, last, replacement in pieces:
        out.append(text[at:starts[first - 1]])
        out.append(replacement)
        at = int(starts[last])
    out.append(text[at:])
    return "".join(out)


def last_point_of(program: Program, lines: np.ndarray) -> np.ndarray:
    """The index of the last point each of ``lines`` reaches (every one reaches one)."""
    found = np.searchsorted(program.lines_of_points, lines, side="right") - 1
    if np.any(found < 0) or not np.array_equal(program.lines_of_points[found], lines):
        raise ValueError("a line that reaches no point")
    return found


def lines_holding(program: Program, chars: str) -> np.ndarray:
    """Per line (index = line number, 0 unused): whether any of ``chars`` occurs in it (its ending included)."""
    lines = program.lines
    text = text_of(program)
    starts = lines.starts if isinstance(lines, Lines) else np.cumsum([0] + [len(raw) for raw in lines])
    found = np.zeros(len(lines) + 1, bool)
    if text.isascii():  # a byte per character: one vectorised pass per character (a regex takes ~10x as long)
        codes = np.frombuffer(text.encode("ascii"), np.uint8)
        hit = np.zeros(len(codes), bool)
        for char in chars:
            hit |= codes == ord(char)
        at = np.flatnonzero(hit)
    else:
        at = np.fromiter((m.start() for m in re.finditer(f"[{re.escape(chars)}]", text)), np.int64)
    found[np.searchsorted(starts, at, side="right")] = True
    return found


def occurs(program: Program, pattern: re.Pattern) -> bool:
    """Whether ``pattern`` occurs in a line of the program, for a pattern no plain line can hold (the
    scanner's G0 / G1 motion lines, ``program.plain``): only the other lines are searched, where they are
    few (a CAM program's millions of motion lines are not)."""
    others = None if program.plain is None else np.flatnonzero(~program.plain)
    if others is None or len(others) > len(program.lines) // 4:  # (the pattern spans no line end: the same)
        return bool(pattern.search(text_of(program)))
    lines = program.lines
    return any(pattern.search(lines[index]) for index in others.tolist())


def feed_lines(program: Program, movable: np.ndarray) -> np.ndarray:
    """Per line (index = line number): whether it is a ``movable`` line (index = line - 1) holding an F word
    (the only lines an arc may replace; any other line, a parameter's ``#<safe> = 5`` too, stays unread)."""
    out = np.zeros(len(program.lines) + 1, bool)
    for line in np.flatnonzero(lines_holding(program, _LETTER_F)[1:] & movable) + 1:
        out[line] = has_feed(program, int(line))
    return out


def sets_motion(program: Program, line: int) -> bool:
    """Whether ``line`` holds a motion-mode word (G0-G3, G5.x, G33.x, G38.x, G73, G76, G80-G89)."""
    words = tokenize(program.lines[line - 1].rstrip("\r\n"), program.source, line).words
    return any(w.letter == "G" and (w.value in MOTION_CODES or 80 <= w.value <= 89 or int(w.value) == 38)
               for w in words)


def has_feed(program: Program, line: int) -> bool:
    raw = program.lines[line - 1]
    if "F" not in raw and "f" not in raw:  # most lines: no letter to tokenize for
        return False
    return any(w.letter == "F" for w in tokenize(program.lines[line - 1].rstrip("\r\n"), program.source,
                                                 line).words)
