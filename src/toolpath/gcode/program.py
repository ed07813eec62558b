"""What reading a program gives: its lines, the tool positions its motion reaches, and the modal state
after every line, held in columns (a million-line program is a few arrays, not a million objects)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

MM_PER_INCH = 25.4


class Motion(IntEnum):
    """Motion kind of the move that arrives at a point."""

    RAPID = 0
    FEED = 1
    ARC = 2


@dataclass
class LineState:
    """Modal state after one line, for the writer to replace motion faithfully."""

    motion: int | None
    absolute: bool
    inch: bool
    position: tuple[float, float, float]
    offset: tuple[float, float, float]
    feed: float | None


class StateTable(Sequence):
    """The modal state after every line (row 0: before the first line), one array per field.

    ``motion`` is -1 where no motion mode is in effect (after G80), ``feed`` NaN before any F word;
    ``offset_id`` indexes ``offsets``, the G92 offsets the program used (they change rarely).
    Indexing gives a :class:`LineState` with ``None`` for those.

    ``blind`` is True after a line the reader passed through without following it (a probe, a canned
    cycle, cutter compensation, an XZ arc: :class:`toolpath.gcode.interpreter.ReaderOptions`'s
    ``pass_through``) and while the X or Y the controller stands at is unknown to the reader after one;
    ``reason_id`` indexes ``reasons``, the construct that made it so (0: none).  ``special`` is True where
    the reader's state holds more than these columns (a plane other than XY, compensation, a cycle).
    """

    COLUMNS = ("motion", "absolute", "inch", "position", "offset_id", "feed", "blind", "special", "reason_id")

    def __init__(self, rows: int) -> None:
        self.motion = np.full(rows, -1, np.int8)
        self.absolute = np.ones(rows, bool)
        self.inch = np.zeros(rows, bool)
        self.position = np.zeros((rows, 3))
        self.offset_id = np.zeros(rows, np.int32)
        self.offsets: list[tuple[float, float, float]] = [(0.0, 0.0, 0.0)]
        self.feed = np.full(rows, np.nan)
        self.blind = np.zeros(rows, bool)
        self.special = np.zeros(rows, bool)
        self.reason_id = np.zeros(rows, np.int32)
        self.reasons: list[str] = [""]

    def __len__(self) -> int:
        return len(self.motion)

    def __getitem__(self, row):  # noqa: ANN001 - an int or a slice, as any sequence
        if isinstance(row, slice):
            return [self[k] for k in range(*row.indices(len(self)))]
        motion, feed = int(self.motion[row]), float(self.feed[row])
        return LineState(None if motion < 0 else motion, bool(self.absolute[row]), bool(self.inch[row]),
                         tuple(float(v) for v in self.position[row]), self.offsets[self.offset_id[row]],
                         None if np.isnan(feed) else feed)

    @property
    def offset(self) -> np.ndarray:
        """(rows, 3) G92 offset after every line."""
        return np.asarray(self.offsets)[self.offset_id]

    def offset_index(self, offset) -> int:  # noqa: ANN001 - any 3 numbers
        key = tuple(float(v) for v in offset)
        if key != self.offsets[-1]:
            self.offsets.append(key)
        return len(self.offsets) - 1

    def put(self, row: int, motion: int | None, absolute: bool, inch: bool, position, offset, feed,
            blind: bool = False, special: bool = False, reason: str = "") -> None:
        self.motion[row] = -1 if motion is None else motion
        self.absolute[row], self.inch[row] = absolute, inch
        self.position[row] = position
        self.offset_id[row] = self.offset_index(offset)
        self.feed[row] = np.nan if feed is None else feed
        self.blind[row], self.special[row] = blind, special
        if reason and reason != self.reasons[-1]:
            self.reasons.append(reason)
        self.reason_id[row] = len(self.reasons) - 1 if reason else 0

    def reason(self, row: int) -> str:
        """Why the reader does not follow the controller at ``row`` (empty where it does)."""
        return self.reasons[int(self.reason_id[row])]

    def rows(self, first: int, stop: int) -> StateTable:
        """Rows ``first .. stop - 1`` as a table of their own."""
        out = StateTable(0)
        for name in self.COLUMNS:
            setattr(out, name, getattr(self, name)[first:stop])
        out.offsets, out.reasons = self.offsets, self.reasons
        return out

    def then(self, other: StateTable) -> StateTable:
        """This table and ``other``'s rows after its first (which repeats this one's last)."""
        out = StateTable(0)
        for name in ("motion", "absolute", "inch", "position", "feed", "blind", "special"):
            setattr(out, name, np.concatenate([getattr(self, name), getattr(other, name)[1:]]))
        out.offsets = self.offsets + other.offsets
        out.offset_id = np.concatenate([self.offset_id, other.offset_id[1:] + len(self.offsets)]).astype(np.int32)
        out.reasons = self.reasons + other.reasons[1:]
        shifted = np.where(other.reason_id[1:] > 0, other.reason_id[1:] + len(self.reasons) - 1, 0)
        out.reason_id = np.concatenate([self.reason_id, shifted]).astype(np.int32)
        return out

    def fill(self, first: int, stop: int, row: int) -> None:
        """Rows ``first .. stop - 1`` become copies of row ``row``."""
        for name in self.COLUMNS:
            column = getattr(self, name)
            column[first:stop] = column[row]


class Lines(Sequence):
    """A program's lines, each with its own ending, as slices of its text (no string per line is kept)."""

    def __init__(self, text: str, starts: np.ndarray) -> None:
        self.text = text
        self.starts = starts  # len(lines) + 1 offsets; the last is len(text)

    def __len__(self) -> int:
        return len(self.starts) - 1

    def __getitem__(self, index):  # noqa: ANN001 - an int or a slice, as any sequence
        if isinstance(index, slice):
            return [self[k] for k in range(*index.indices(len(self)))]
        if index < 0:
            index += len(self)
        if not 0 <= index < len(self):
            raise IndexError("line index out of range")
        return self.text[self.starts[index]:self.starts[index + 1]]

    def __iter__(self) -> Iterator[str]:
        text, starts = self.text, self.starts.tolist()
        return (text[a:b] for a, b in zip(starts[:-1], starts[1:], strict=True))

    def joined(self, replacements: dict[int, str]) -> str:
        """The text with line ``k`` (1-based) replaced by ``replacements[k]``; other lines untouched."""
        out, at = [], 0
        for lineno in sorted(replacements):
            out.append(self.text[at:self.starts[lineno - 1]])
            out.append(replacements[lineno])
            at = int(self.starts[lineno])
        out.append(self.text[at:])
        return "".join(out)


@dataclass
class Program:
    """A read program: its raw lines and the tool positions its motion reaches.

    ``points`` (n, 3) are in mm in the frame of the program's start (G92 shifts applied);
    ``kinds`` holds :class:`Motion` values; ``lines_of_points`` the 1-based source line of each.
    ``states[k]`` is the modal state after line ``k`` (``states[0]``: before the first line).
    ``plain[k - 1]`` is True when line ``k`` is a plain ``G0/G1 X Y Z F N`` line
    (:mod:`toolpath.gcode.scanner`), and ``xy_decimals[k - 1]`` the decimals of its X / Y numbers.
    """

    source: str
    lines: Sequence[str]
    points: np.ndarray
    kinds: np.ndarray
    lines_of_points: np.ndarray
    units: str
    states: StateTable = field(repr=False)
    plain: np.ndarray | None = field(default=None, repr=False)
    xy_decimals: np.ndarray | None = field(default=None, repr=False)
    first_line: int = 1  # where line 1 sits in the file, for a part of a program read in parts

    def split(self, count: int) -> tuple[Program, Program]:
        """(lines 1..count, the rest), each numbered from 1; the rest's ``states[0]`` is ``states[count]``."""
        text, starts = self.lines.text, self.lines.starts
        at = int(starts[count])
        cut = int(np.searchsorted(self.lines_of_points, count, side="right"))
        head = Program(self.source, Lines(text[:at], starts[:count + 1]), self.points[:cut], self.kinds[:cut],
                       self.lines_of_points[:cut], self.units, self.states.rows(0, count + 1),
                       None if self.plain is None else self.plain[:count],
                       None if self.xy_decimals is None else self.xy_decimals[:count], self.first_line)
        tail = Program(self.source, Lines(text[at:], starts[count:] - at), self.points[cut:], self.kinds[cut:],
                       self.lines_of_points[cut:] - count, self.units, self.states.rows(count, len(self.states)),
                       None if self.plain is None else self.plain[count:],
                       None if self.xy_decimals is None else self.xy_decimals[count:], self.first_line + count)
        return head, tail

    def then(self, other: Program) -> Program:
        """This part followed by the part read right after it (``other.states[0]`` is this one's last row)."""
        shift = len(self.lines)
        starts = np.concatenate([self.lines.starts, other.lines.starts[1:] + len(self.lines.text)])

        def joined(a, b):  # noqa: ANN001, ANN202 - two optional arrays
            return None if a is None or b is None else np.concatenate([a, b])

        return Program(self.source, Lines(self.lines.text + other.lines.text, starts),
                       np.concatenate([self.points, other.points]), np.concatenate([self.kinds, other.kinds]),
                       np.concatenate([self.lines_of_points, other.lines_of_points + shift]).astype(np.int32),
                       other.units, self.states.then(other.states), joined(self.plain, other.plain),
                       joined(self.xy_decimals, other.xy_decimals), self.first_line)

    @property
    def feed_mask(self) -> np.ndarray:
        """True where a point is reached by cutting motion (G1, G2, G3)."""
        return self.kinds != Motion.RAPID
