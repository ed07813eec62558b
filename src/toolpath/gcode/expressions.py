"""Parameters and expressions as LinuxCNC reads them (RS-274/NGC; the LinuxCNC manual, "Numbered
Parameters", "Named Parameters", "Expressions", "Binary Operators", "Functions").

* ``#1``..``#5602`` numbered parameters (0 until set); ``#<name>`` named parameters, case and blanks
  ignored, an error when read before they are set; ``#<_name>`` global ones (this reader keeps one
  scope: there are no subroutines); ``##2`` indirect.
* ``[ ... ]`` expressions with ``**``; ``* / MOD``; ``+ -``; ``EQ NE GT GE LT LE``; ``AND OR XOR``
  (precedence in that order, left to right), unary minus and plus, and the functions ``ABS ACOS
  ASIN COS EXP FIX FUP ROUND LN SIN SQRT TAN`` (degrees), ``ATAN[y]/[x]`` and ``EXISTS[#<name>]``.
* Assignments ``#n = value`` take effect after the whole line has been read, so every value on a
  line sees the parameters as they were before it.
"""

from __future__ import annotations

import math
import re

_NUMBER = re.compile(r"[+-]?\s*(\d+\.?\d*|\.\d+)")
_MAX_NUMBERED = 5602
_FUNCTIONS = {
    "ABS": abs, "ACOS": lambda v: math.degrees(math.acos(v)), "ASIN": lambda v: math.degrees(math.asin(v)),
    "COS": lambda v: math.cos(math.radians(v)), "EXP": math.exp, "FIX": math.floor, "FUP": math.ceil,
    "ROUND": lambda v: float(math.floor(v + 0.5)) if v >= 0 else -float(math.floor(-v + 0.5)), "LN": math.log,
    "SIN": lambda v: math.sin(math.radians(v)), "SQRT": math.sqrt, "TAN": lambda v: math.tan(math.radians(v)),
}
_MAX_DEPTH = 32  # nested brackets, functions and unary signs (each costs Python stack; LinuxCNC's lines are short)
# binary operators by precedence level (lowest first), as the manual's table
_LEVELS = (("AND", "OR", "XOR"), ("EQ", "NE", "GT", "GE", "LT", "LE"), ("+", "-"), ("*", "/", "MOD"), ("**",))


class ExpressionError(ValueError):
    """What is wrong with a parameter or expression (the lexer adds file and line)."""


#: LinuxCNC's read-only named parameters (``interp_namedparams.cc``): the controller's state (position,
#: modes, tool, overrides), which a reader of the text alone does not know; so are ``_hal[pin]`` and
#: ``_ini[section]name`` reads
_CONTROLLER_NAMES = (
    "line motion_mode plane ccomp metric imperial absolute incremental inverse_time units_per_minute "
    "units_per_rev coord_system tool_offset retract_r_plane retract_old_z control_mode spindle_rpm_mode "
    "spindle_css_mode ijk_absolute_mode lathe_diameter_mode lathe_radius_mode spindle_on spindle_cw mist flood "
    "speed_override feed_override adaptive_feed feed_hold feed rpm current_tool current_pocket selected_pocket "
    "selected_tool x y z a b c u v w abs_x abs_y abs_z abs_a abs_b abs_c abs_u abs_v abs_w value value_returned "
    "task call_level remap_level")
CONTROLLER_NAMES = frozenset(_CONTROLLER_NAMES.split())


def controller_name(key: str) -> bool:
    """Whether named parameter ``key`` (lower case, no blanks) is one only the controller knows."""
    return (key.startswith("_") and key[1:] in CONTROLLER_NAMES) or key.startswith(("_hal[", "_ini["))


class Parameters:
    """The parameter table of one program run.  ``controller_as_zero``: a read of the controller's own
    state (:func:`controller_name`) gives 0 where the caller stops following the program there."""

    def __init__(self, controller_as_zero: bool = False) -> None:
        self.numbered: dict[int, float] = {}
        self.named: dict[str, float] = {}
        self.controller_as_zero = controller_as_zero

    def get(self, key: int | str) -> float:
        if isinstance(key, str):
            if key not in self.named:
                if controller_name(key):
                    if self.controller_as_zero:
                        return 0.0
                    raise ExpressionError(f"#<{key}> is the controller's state, which a reader of the program "
                                          "text does not know")
                raise ExpressionError(f"named parameter #<{key}> is read before it is set")
            return self.named[key]
        return self.numbered.get(key, 0.0)

    def set(self, key: int | str, value: float) -> None:
        if isinstance(key, str):
            self.named[key] = value
        else:
            self.numbered[key] = value


class Scanner:
    """Reads values from one comment-free line body, starting at ``pos``."""

    def __init__(self, body: str, params: Parameters, pos: int = 0) -> None:
        self.s, self.params, self.pos = body, params, pos
        self.depth = 0

    def _skip(self) -> None:
        while self.pos < len(self.s) and self.s[self.pos] in " \t":
            self.pos += 1

    def _peek_word(self, words: tuple[str, ...]) -> str | None:
        self._skip()
        rest = self.s[self.pos:self.pos + 3].upper()  # the longest operator; no copy of the whole line
        for w in sorted(words, key=len, reverse=True):
            if rest.startswith(w) and not (w == "*" and rest.startswith("**")):
                return w
        return None

    def value(self) -> float:
        """A real value: a number, a parameter, a bracketed expression or a function, with an optional sign.
        A value that is not finite is an error (it would reach the tool path as a NaN)."""
        self.depth += 1
        try:
            if self.depth > _MAX_DEPTH:
                raise ExpressionError(f"an expression is nested deeper than {_MAX_DEPTH} levels")
            result = self._value()
        finally:
            self.depth -= 1
        if not math.isfinite(result):
            raise ExpressionError(f"a value overflows ({result})")
        return result

    def _value(self) -> float:
        self._skip()
        if self.pos >= len(self.s):
            raise ExpressionError("a value is missing at the end of the line")
        ch = self.s[self.pos]
        if ch in "+-":
            match = _NUMBER.match(self.s, self.pos)
            if match:
                self.pos = match.end()
                return float(match.group(0).replace(" ", ""))
            self.pos += 1
            inner = self.value()
            return -inner if ch == "-" else inner
        if ch.isdigit() or ch == ".":
            match = _NUMBER.match(self.s, self.pos)
            if match is None:
                raise ExpressionError(f"a number is malformed at {self.s[self.pos:self.pos + 8]!r}")
            self.pos = match.end()
            return float(match.group(0))
        if ch == "#":
            return self.params.get(self.parameter_key())
        if ch == "[":
            return self.bracket()
        return self.function()

    def parameter_key(self) -> int | str:
        """After ``#``: a number (or value: ``##2``, ``#[1+1]``) or ``<name>``."""
        self.pos += 1
        self._skip()
        if self.s.startswith("<", self.pos):
            close = self.s.find(">", self.pos)
            if close < 0:
                raise ExpressionError("a named parameter '#<' is never closed with '>'")
            name = re.sub(r"\s+", "", self.s[self.pos + 1:close]).lower()
            if not name:
                raise ExpressionError("a named parameter has no name")
            self.pos = close + 1
            return name
        number = self.value()
        if number != int(number) or not 1 <= number <= _MAX_NUMBERED:
            raise ExpressionError(f"parameter number {number:g} is not an integer in 1-{_MAX_NUMBERED}")
        return int(number)

    def bracket(self) -> float:
        self._skip()
        if not self.s.startswith("[", self.pos):
            raise ExpressionError(f"expected '[' at {self.s[self.pos:self.pos + 8]!r}")
        self.pos += 1
        result = self._binary(0)
        self._skip()
        if self.pos >= len(self.s):
            raise ExpressionError("an expression '[' is never closed with ']'")
        if not self.s.startswith("]", self.pos):
            raise ExpressionError(f"unexpected {self.s[self.pos:self.pos + 8]!r} in an expression "
                                  "(an operator or ']' should follow a value)")
        self.pos += 1
        return result

    def _binary(self, level: int) -> float:
        if level == len(_LEVELS):
            return self.value()
        left = self._binary(level + 1)
        while (op := self._peek_word(_LEVELS[level])) is not None:
            self.pos += len(op)
            left = _apply(op, left, self._binary(level + 1))
        return left

    def function(self) -> float:
        match = re.compile(r"[A-Za-z]+").match(self.s, self.pos)
        name = match.group(0).upper() if match else ""
        if name == "EXISTS":
            self.pos = match.end()
            self._skip()
            if not self.s.startswith("[", self.pos):
                raise ExpressionError("EXISTS takes [#<name>]")
            self.pos += 1
            self._skip()
            if not self.s.startswith("#", self.pos):
                raise ExpressionError("EXISTS takes [#<name>]")
            key = self.parameter_key()
            self._skip()
            if not self.s.startswith("]", self.pos):
                raise ExpressionError("EXISTS[ is never closed with ']'")
            self.pos += 1
            return float(key in self.params.named) if isinstance(key, str) else 1.0
        if name == "ATAN":
            self.pos = match.end()
            y = self.bracket()
            self._skip()
            if not self.s.startswith("/", self.pos):
                raise ExpressionError("ATAN takes [y]/[x]")
            self.pos += 1
            return math.degrees(math.atan2(y, self.bracket()))
        if name in _FUNCTIONS:
            self.pos = match.end()
            argument = self.bracket()
            try:
                return float(_FUNCTIONS[name](argument))
            except (ValueError, OverflowError):
                raise ExpressionError(f"{name}[{argument:g}] is undefined") from None
        raise ExpressionError(f"unexpected {self.s[self.pos:self.pos + 8]!r} where a value should be")


def _apply(op: str, a: float, b: float) -> float:
    try:
        if op == "**":
            return float(a**b) if not (a < 0 and b != int(b)) else _undefined(op, a, b)
        if op == "/":
            return a / b if math.isfinite(a / b) else _undefined(op, a, b)
        if op == "MOD":  # as LinuxCNC: fmod, then made non-negative
            r = math.fmod(a, b)
            return r + abs(b) if r < 0 else r
    except (ZeroDivisionError, OverflowError, ValueError):
        return _undefined(op, a, b)
    result = {"*": a * b, "+": a + b, "-": a - b, "EQ": float(a == b), "NE": float(a != b), "GT": float(a > b),
            "GE": float(a >= b), "LT": float(a < b), "LE": float(a <= b), "AND": float(bool(a) and bool(b)),
            "OR": float(bool(a) or bool(b)), "XOR": float(bool(a) != bool(b))}[op]
    return result if math.isfinite(result) else _undefined(op, a, b)


def _undefined(op: str, a: float, b: float) -> float:
    raise ExpressionError(f"{a:g} {op} {b:g} is undefined")
