"""What the reader reads past without following it (``ReaderOptions.pass_through``, ``toolpath smooth``).

A controller runs many things the smoothing has no business changing: G10 offset tables, arcs of the XZ / YZ planes
(Fusion 360's lead-ins), G5 splines, canned cycles, cutter compensation, probing, homing, moves in
machine coordinates, O-word subroutines and loops, M98 / M99.  Refusing the whole program for one of
them leaves a machinist with nothing; following them would take the controller's own state (tool
radius, probe contact, stored homes, work offsets).  So the reader reads past them: the line emits no
point (an arc of another plane or a spline: one rapid-kind point at its end, where its end is known,
which ends a feed run there), and where the controller's X or Y is then unknown to the reader, every
row after it is ``blind`` until a move states that axis in absolute mode (or G92 sets it).  A window
holding a blind row is kept as written, with the construct's reason.  From an O-word or M98 / M99 on
the reader follows nothing more: the rest of the program is passed through.

A whole program is refused only where its own controller would refuse it: an ``O1234`` line alone is a
Fanuc / Haas program number (``--dialect fanuc``), which LinuxCNC refuses.
"""

from __future__ import annotations

import re

XY = frozenset("XY")
CYCLES = frozenset(range(73, 90)) - {80}
_PLANES = {17: "XY", 18: "XZ", 19: "YZ"}
_PROBES = {31, 38.2, 38.3, 38.4, 38.5}  # G31: Mach3 / Mach4 (and Fanuc's skip) probing
_PROGRAM_NUMBER = re.compile(r"\s*[oO]\s*\d+\s*$")
_INTEGER_AXIS = re.compile(r"([XYZIJKRxyzijkr])\s*([+-]?\s*0*[1-9]\d*)(?![\d.])")  # X0 is 0 either way
_DECIMAL_LETTERS = "XYZIJKR"
# grbl 1.1's system commands ($ help, $$ $# $G $I $N $C $X $SLP reports and modes, $n=value settings,
# $Nn=line start-up blocks, $H homing, $J= jogging, $RST= resets) and its real-time characters on a line of
# their own; LinuxCNC's "$2" (a spindle number) and other tools' "$Name" directives are not among them
_GRBL_COMMAND = re.compile(r"\s*(\$(?:\$|#|G|C|X|SLP|I(?:=.*)?|N(?:\d+\s*=.*)?|H[XYZABC]*|J=.*|RST=[$#*]"
                           r"|\d+\s*=\s*[-+]?[\d.]+)?|[?~!]+)\s*$", re.IGNORECASE)
_GRBL_MOVING = {"$H": "homing", "$J": "jogging", "$RST": "a reset of the stored offsets"}


def grbl_command(text: str) -> str | None:
    """The grbl system or real-time command a line (comments removed) is, or None."""
    match = _GRBL_COMMAND.match(text)
    return match.group(1).strip() if match else None


def integer_word_problem(letter: str, text: str) -> str:
    return (f"{letter}{text}: an axis word without a decimal point, which a Fanuc / Haas control without "
            f"decimal-point input reads as {text.replace(' ', '')} least increments, not {text.replace(' ', '')} "
            f"units: write {letter}{text}. (or pass --whole-integer-words if this control reads it as whole units)")


def integer_word_in(text: str) -> tuple[int, str] | None:
    """The first axis word without a decimal point in ``text`` (plain lines: no comments, no expressions),
    as (its line's index in ``text``, the problem), or None."""
    match = _INTEGER_AXIS.search(text)
    if match is None:
        return None
    return text.count("\n", 0, match.start()), integer_word_problem(match.group(1).upper(), match.group(2))


class PassThrough:
    """The pass-through half of the interpreter: its state and what it does with such a line."""

    def init_passing(self) -> None:
        self.plane = 17
        self.comp: str | None = None  # "G41" / "G42" while cutter compensation is on
        self.unknown: set[str] = set()  # axes (of X, Y) where the controller stands, unknown to the reader
        self.why = ""  # the latest construct read past, for the rows it makes blind
        self.opaque = False  # the line being read was read past
        self.stopped: str | None = None  # from an O-word or M98 / M99 on the reader follows nothing
        self.stored = {28: False, 30: False}  # G28.1 / G30.1 seen: the return positions are the program's

    def stepping(self) -> bool:
        """Whether plain lines must go one by one (their effect depends on state the batch does not keep)."""
        return bool(self.unknown) or self.comp is not None or self.stopped is not None or self.motion in CYCLES

    def special(self) -> bool:
        """Whether the state holds more than a :class:`~toolpath.gcode.program.StateTable` row."""
        return self.stepping() or self.plane != 17

    def blind(self) -> bool:
        return self.opaque or bool(self.unknown) or self.stopped is not None

    def _past(self, lineno: int, what: str, axes=frozenset()) -> None:  # noqa: ANN001 - any set of letters
        self.opaque = True
        self.unknown |= set(axes) & XY
        self.why = f"{what} at line {lineno}"

    def stop_following(self, lineno: int, what: str) -> None:
        self.opaque = True
        self.stopped = self.why = f"{what} at line {lineno}: the reader follows nothing after it"

    def o_line(self, body: str, lineno: int) -> None:
        """An O-word line: a Fanuc program number (ignored) or control flow (nothing followed after it)."""
        if _PROGRAM_NUMBER.match(body):
            if self.opt.dialect == "fanuc":
                return
            raise self.fail(lineno, f"{body.strip()} alone is a Fanuc / Haas program number, which LinuxCNC "
                                    "refuses (an O-word needs sub, call, if, while...): pass --dialect fanuc")
        self.stop_following(lineno, "O-word control flow")

    def grbl_line(self, command: str, lineno: int) -> None:
        """A grbl system command (``$$``, ``$H``, ``$J=...``) or real-time character line: under ``--dialect
        grbl`` a report, setting or unlock moves nothing; homing, jogging and an offset reset leave the
        position to the machine (read past, X Y unknown).  Other controls refuse the line."""
        if self.opt.dialect != "grbl":
            raise self.fail(lineno, f"{command[:20]} is a grbl system command, which LinuxCNC and Fanuc controls "
                                    "refuse: pass --dialect grbl")
        upper = command.upper()
        prefix = next((p for p in _GRBL_MOVING if upper.startswith(p)), None)
        if prefix is None:
            return
        moving = _GRBL_MOVING[prefix]
        if not self.opt.pass_through:
            raise self.fail(lineno, f"grbl {command[:20]} ({moving}) is not supported: the position after it is "
                                    "the machine's")
        self._past(lineno, f"grbl {prefix} ({moving})", XY)

    def check_decimal_points(self, words, lineno: int) -> None:  # noqa: ANN001 - the line's words
        """``--dialect fanuc``: an axis or arc word written without a decimal point is refused."""
        for w in words:
            if w.letter in _DECIMAL_LETTERS and "." not in w.text and w.text[:1] not in "[#" and w.value != 0:
                raise self.fail(lineno, integer_word_problem(w.letter, w.text))

    def pass_codes(self, code: float, major: int) -> str | None:
        """How the pass-through reads G ``code``: ``motion`` (a canned cycle), ``other`` or None (not its)."""
        if code == major and major in CYCLES:
            return "motion"
        if code in (7, 10, 18, 19, 41, 42, 41.1, 42.1, 53, 5, 5.1, 28.2, 28.3) or code in _PROBES:
            return "other"
        return None

    def read_past(self, motion: int | None, others: list[float], values: dict[str, float], lineno: int) -> bool:
        """Apply this line's pass-through codes; True when the line is done (read past)."""
        for code in others:
            if code in _PLANES:
                self.plane = int(code)
            elif code == 40:
                self.comp = None
            elif code in (41, 42, 41.1, 42.1):
                self.comp = f"G{code:g}"
        axes = [a for a in "XYZ" if a in values]
        if 7 in others:
            self.stop_following(lineno, "G7 (lathe diameter mode: X is a diameter)")
            return True
        if polar := [a for a in "@^" if a in values]:  # LinuxCNC's polar words: a move the reader does not follow
            if motion is not None:
                self.motion = motion
            self._past(lineno, f"polar coordinates ({' '.join(polar)})", XY)
            return True
        if 10 in others:  # its axis words are offsets, not a move; L2 / L20 move the work coordinates themselves
            table = values.get("L", 0) in (2, 20)
            self._past(lineno, f"G10 L{values.get('L', 0):g} ({'work offsets' if table else 'tool table'} set)",
                       XY if table else ())
            return True
        if probe := next((c for c in others if c in _PROBES), None):
            self._past(lineno, f"G{probe:g} probing", axes or "XYZ")
            return True
        if home := next((c for c in others if c in (28.2, 28.3)), None):
            self._past(lineno, f"G{home:g} homing", axes or "XYZ")
            return True
        if 53 in others:
            if motion is not None:  # G53 is for this line; its G0 / G1 stays the motion mode
                self.motion = motion
            self._past(lineno, "G53 (machine coordinates)", axes)
            return True
        if motion in CYCLES or (motion is None and self.motion in CYCLES and axes):
            if motion is not None:
                self.motion = motion
            self._past(lineno, f"canned cycle G{self.motion}", XY)
            return True
        spline = next((c for c in others if c in (5, 5.1)), None)
        arc = (motion if motion is not None else self.motion) in (2, 3)
        if spline is not None or (self.plane != 17 and arc and (axes or motion is not None)):  # or a full circle
            if motion is not None:
                self.motion = motion
            target = self._target(values)
            self._emit(target[None, :], 0, lineno)  # Motion.RAPID: not a feed move the windows cut
            self.pos = target
            name = f"G{spline:g} spline" if spline is not None else \
                f"G{self.motion} arc in the {_PLANES[self.plane]} plane (G{self.plane})"
            self._past(lineno, name)
            return True
        if self.comp is not None and axes:
            self._past(lineno, f"cutter compensation {self.comp}", XY)
        return False

    def other_words(self, values: dict[str, float], m_codes: set[int], lineno: int) -> None:
        """Words of a line beyond XYZ milling: E is the channel of M66 / M67 / M68; A B C U V W move axes
        the reader does not follow (the line is read past, its XYZ move followed); @ ^ are polar words."""
        if "E" in values and not m_codes & {66, 67, 68}:
            raise self.fail(lineno, "axis word E is not supported (XYZ milling only)")
        if moving := [a for a in "ABCUVW" if a in values]:
            if not self.opt.pass_through:
                raise self.fail(lineno, f"axis word {moving[0]} is not supported (XYZ milling only)")
            self._past(lineno, f"a move of axis {' '.join(moving)}")
        if not self.opt.pass_through and ("@" in values or "^" in values):
            raise self.fail(lineno, "polar coordinates (@ ^) are not supported")

    def moved(self, values: dict[str, float]) -> None:
        """After a move: an axis stated in absolute mode is known again (not under compensation)."""
        if self.unknown and self.absolute and self.comp is None:
            self.unknown -= set(values)

    def offset_set(self, values: dict[str, float]) -> None:
        """G92 on an unknown axis: the program's coordinates are the given ones from here on, and every
        later position differs from the controller's by one constant shift, which smoothing does not see."""
        self.unknown -= set(values)

    def homed(self, code: int, axes, lineno: int) -> None:  # noqa: ANN001 - the axes moved
        """G28 / G30 to a position the program did not store (no G28.1 / G30.1): the controller's own."""
        if not self.stored[code]:
            self._past(lineno, f"G{code} to a position the program never stored (G{code}.1)", axes)
