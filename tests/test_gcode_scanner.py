"""The vectorised scanner and the plain-line runs of the reader: the same program, bit for bit, as the
line-by-line interpreter, and the same errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from toolpath.gcode import GCodeError, read_text
from toolpath.gcode.lexer import tokenize
from toolpath.gcode.scanner import LETTERS, line_bounds, scan
from toolpath.gcode.text import split_lines


def _same(text: str) -> None:
    """Both readers give the same program, or the same error."""
    try:
        slow = read_text(text, vectorise=False)
    except GCodeError as exc:
        with pytest.raises(GCodeError) as caught:
            read_text(text)
        assert str(caught.value) == str(exc)
        return
    fast = read_text(text)
    assert fast.points.tobytes() == slow.points.tobytes()
    assert np.array_equal(fast.kinds, slow.kinds) and np.array_equal(fast.lines_of_points, slow.lines_of_points)
    for column in ("motion", "absolute", "inch", "position", "offset", "feed"):
        a, b = getattr(fast.states, column), getattr(slow.states, column)
        assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), column
    assert list(fast.lines) == list(slow.lines) == split_lines(text)
    assert fast.units == slow.units


@pytest.mark.parametrize("text", [
    "G1 X1.5 Y-2 F100\nX.5\nY-.25 Z+3\n",
    "g1x1y2\nn10 g0 x3\r\nG01 X4\rG00Y5",
    "G91\nG1 X1 Y1\nX1\nX1 Y-0.5\nG90\nX0\n",
    "G20\nG1 X1 Y1 F10\nX2\nG21\nX3\n",
    "G92 X10\nG1 X1\nX2\nG92.1\nX3\n",
    "G80\nX1\n", "G2 X1 Y1 I1\nX2\n", "G1 X1 M30\nX5\n", "%\nG1 X1\n%\nX9\n",
    "G1 X1\n\n   \n\tX2\n", "G1 X1 X2\n", "G1 G0 X1\n", "G2 X1\n", "X1.2.3\n", "X1-2\n", "X\n", "1\n",
    "X1234567890123456\n", "X1e5\n", "G1 X1000000001\n", "G1 X999999999.99999\n", "G1X1(c)\n", "G1 X#1\n",
    "G1 X1 ; c\n", "/G1 X1\n", "G1 X 1\n", "G1 X- 1\n", "G17 G1 X1\n", "G1.0 X1\nG01.0 X2\n", "\ufeffG1 X1\n",
    "G1 X1\nG1 Y\u00e92\n", "F100\nG1 X1\n", "G1 N-3 X1 F-100\n",
])
def test_plain_runs_read_as_the_interpreter_does(text):
    _same(text)


def test_every_number_is_bit_identical_to_the_lexer_s():
    rng = np.random.default_rng(0)
    numbers = [f"{v:.{d}f}" for v, d in zip(rng.normal(0, 10.0 ** rng.integers(-3, 8, 4000)),
                                            rng.integers(0, 9, 4000), strict=True)]
    numbers += ["0", "-0", "+0.0", ".5", "-.5", "5.", "000123.4500", "999999999", "0.000000000000001"]
    text = "".join(f"G1 X{n}\n" for n in numbers)
    lines = scan(text)
    long = np.array([sum(c.isdigit() for c in n) > 15 for n in numbers])
    assert long.any() and np.array_equal(lines.fast, ~long)  # past 15 digits: left to the lexer
    got = lines.values[LETTERS.index("X"), ~long]
    expected = [tokenize(f"X{n}").words[0].value for n, skip in zip(numbers, long, strict=True) if not skip]
    assert got.tobytes() == np.array(expected).tobytes()


@pytest.mark.parametrize("text", ["", "a", "a\n", "a\r\nb", "a\rb\r", "\n\n", "a\r\r\nb\n", "\r"])
def test_line_bounds_split_as_controllers_do(text):
    codes = np.frombuffer(text.encode(), np.uint8)
    starts, body_ends = line_bounds(codes)
    lines = split_lines(text)
    assert [text[a:b] for a, b in zip(starts[:-1], starts[1:], strict=True)] == lines
    assert [text[a:b] for a, b in zip(starts[:-1], body_ends, strict=True)] == [s.rstrip("\r\n") for s in lines]


def test_a_plain_line_keeps_its_decimals_for_the_rewrite():
    s = scan("G1 X1.250 Y-3\nG1 Y2.5\n(X1.0)\n")
    assert s.decimals.tolist() == [[3, 0], [-1, 1], [-1, -1]]
    assert s.fast.tolist() == [True, True, False]


_PLAIN_WORDS = st.sampled_from(["G0", "G1", "G01", "G2", "G90", "G91", "G20", "G21", "G92", "M30", "F", "N", "X", "Y",
                                "Z", "I", "(c)", "/", "%", "#1=2", "X#1", " ", "\t", "x", "g1"])
_VALUES = st.one_of(st.integers(-10**6, 10**6).map(str), st.floats(-1e4, 1e4).map(lambda v: f"{v:.3f}"),
                    st.sampled_from(["", ".", "-", "1.2.3", "9" * 17, ".5", "-.5"]))
_LINE = st.lists(st.tuples(_PLAIN_WORDS, _VALUES).map("".join), max_size=5).map(" ".join)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(_LINE, max_size=12), st.sampled_from(["\n", "\r\n", "\r"]))
def test_any_program_reads_the_same_vectorised_or_line_by_line(lines, ending):
    _same(ending.join(lines))
