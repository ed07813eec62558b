"""How the G-code reader reads: :class:`ReaderOptions` (every field is in ``conf/gcode/``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

DIALECTS = ("linuxcnc", "fanuc", "grbl")


@dataclass(frozen=True)
class ReaderOptions:
    """How to read; every field is in ``conf/gcode/``.

    chord_tolerance : max sagitta (mm) of the chords that replace an arc.
    initial_motion : motion mode before any G word (0 = rapid, as Grbl and TinyG power up).
    block_delete : True honours ``/`` (skips those lines), as with the switch on.
    pass_through : what the reader does not follow (other planes' arcs, canned cycles, cutter compensation,
        probing, homing, G53, O-word control flow, M98 / M99) is read past instead of refused
        (:mod:`toolpath.gcode.passing`): such a line emits no point (an arc of another plane or a G5 spline
        a rapid-kind point at its end, which breaks a feed run there), and the rows after it are
        ``blind`` in the :class:`~toolpath.gcode.program.StateTable` until the reader knows X and Y again.
    dialect : ``linuxcnc`` (default), ``fanuc`` (an ``O1234`` line is a program number, an axis word
        without a decimal point is refused: on a control without decimal-point input it counts least
        increments) or ``grbl`` (a line of a ``$`` system command or of real-time ``? ~ !`` characters is
        grbl's: homing, jogging and an offset reset are read past, the rest moves nothing).
    whole_integer_words : under ``fanuc``, an axis word without a decimal point is read as whole units (a
        control set to calculator-type decimal input, or Mach3) instead of refused.
    """

    chord_tolerance: float = 0.001
    initial_motion: int = 0
    block_delete: bool = False
    pass_through: bool = False
    dialect: str = "linuxcnc"
    whole_integer_words: bool = False  # fanuc: X4 is 4 units (Fanuc's calculator-type input, Mach3), not refused

    def __post_init__(self) -> None:
        if not (isinstance(self.chord_tolerance, int | float) and 0 < self.chord_tolerance < math.inf):
            raise ValueError(f"chord_tolerance must be a number > 0 (mm), not {self.chord_tolerance!r}")
        if self.initial_motion not in (0, 1):
            raise ValueError(f"initial_motion must be 0 (rapid) or 1 (feed), not {self.initial_motion!r}")
        if not isinstance(self.whole_integer_words, bool):
            raise ValueError(f"whole_integer_words must be true or false, not {self.whole_integer_words!r}")
        if self.dialect not in DIALECTS:
            raise ValueError(f"dialect must be one of {', '.join(DIALECTS)}, not {self.dialect!r}")


