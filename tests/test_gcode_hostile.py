"""Hostile input to the G-code reader and writer (issue 24): every attack gives a correct result or a
GCodeError naming the file and line, within bounded time and memory; never a traceback, never a
silently wrong program."""

import contextlib
import os
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from toolpath.gcode import GCodeError, ReaderOptions, read_file, read_text, replace_motion
from toolpath.gcode.arcs import MAX_ARC_POINTS
from toolpath.gcode.text import MAX_LINE_LENGTH, split_lines
from toolpath.gcode.writer import fmt, fmt_many

# --- correct results: line endings, BOM, program end ----------------------------------------------

@pytest.mark.parametrize("data, expected_xy", [
    # a lone CR inside a CRLF file ends a line, as on a controller: no point is lost
    (b"G21\nG1 X1 Y1 F100\rG1 X2 Y2\r\nG1 X3 Y3\r\n", [[1, 1], [2, 2], [3, 3]]),
    (b"G21\rG1 X1 Y1 F100\rG1 X2\r", [[1, 1], [2, 1]]),                     # CR-only (old Mac)
    (b"\xef\xbb\xbfG21\nG1 X1 F100\n", [[1, 0]]),                           # a UTF-8 BOM
    (b"%\nG1 X1 F100\n%\nG1 X5\n", [[1, 0]]),                                # nothing runs after the closing %
    (b"G1 X1 F100\n%\nG1 X5\n", [[1, 0]]),                                  # a % that opens nothing ends
    (b"G1 X1 F100\nM30\nG1 X@@ garbage\n", [[1, 0]]),                       # after M30 nothing is read
])
def test_line_endings_bom_and_program_end_read_as_a_controller_does(tmp_path, data, expected_xy):
    path = tmp_path / "p.nc"
    path.write_bytes(data)
    program = read_file(path)
    np.testing.assert_allclose(program.points[:, :2], expected_xy)
    assert "".join(program.lines).encode("utf-8", "surrogateescape") == data  # every byte kept for rewriting


def test_split_lines_keeps_every_ending():
    assert split_lines("a\r\nb\rc\nd") == ["a\r\n", "b\r", "c\n", "d"]
    assert split_lines("a\nb\n") == ["a\n", "b\n"]


# --- refused, with the line ---------------------------------------------------------------------

@pytest.mark.parametrize("text, line, fragment", [
    ("G1 X1" + "1" * 300 + " F100\n", 1, "out of range"),
    ("G1 X1 F100\nM2.5\nG1 X2\n", 2, "M2.5 is not an M-code"),
    ("M200\n", 1, "not an M-code"),
    ("G1.05 X1\n", 1, "not a G-code"),
    ("G1 X0 Y0 F100\nG2 X0 Y0 I1 J0 P0\n", 2, "P0 on an arc"),
    ("G1 X0 Y0 F100\nG2 X0 Y0 I1 J0 P-5\n", 2, "P-5 on an arc"),
    ("G1 X0 Y0 F100\nG2 X0 Y0 I1 J0 P2.9\n", 2, "P2.9 on an arc"),
    ("G1 X0 Y0 F100\nG2 X0 Y0 I10 J0 P100000000\n", 2, "more than the limit"),
    ("G1 X0 Y0 F100\nG2 X0 Y0 I999999999 J0\n", 2, "more than the limit"),
    ("G1 X" + "[" * 500 + "1" + "]" * 500 + "\n", 1, "nested deeper"),
    ("G1 X" + "-" * 3000 + "1\n", 1, "nested deeper"),
    ("#1=[10**200*10**200]\n", 1, "undefined"),
    ("#1=[10**300]\nG1 X#1\n", 1, "out of range"),
    ("G1 X[1/0]\n", 1, "undefined"),
    ("G1 X[EXP[1000]]\n", 1, "undefined"),
    ("G1 X1 " + "(" + "c" * (MAX_LINE_LENGTH + 1) + ")\n", 1, "longer than"),
    ("G1 X[1e300*1e300] F100\n", 1, "unexpected 'e300*1e3' in an expression"),  # no exponents in G-code
    ("G1 X0 Y0 F100\nG2 X1 Y0 I0.5 J0 K1\n", 2, "not of the XY plane"),
    # numbers a controller does not read: exponents, non-ASCII digits and blanks (Python's float reads them)
    ("G1 X0 Y0 F100\nG1 X1e12 Y0\n", 2, "X1e12: exponent notation is not G-code"),
    ("G1 X1E-3 F100\n", 1, "X1E-3: exponent notation"),
    ("G1 X\u0663.050 F100\n", 1, "U+0663) outside a comment"),
    ("G1 X1\u00a0Y0 F100\n", 1, "U+00A0) outside a comment"),
])
def test_hostile_text_is_refused_with_its_line(text, line, fragment):
    with pytest.raises(GCodeError) as caught:
        read_text(text, "hostile.nc")
    assert caught.value.line == line and fragment in caught.value.message
    assert str(caught.value).startswith(f"hostile.nc:{line}: ")


def test_a_stream_without_line_ends_is_refused_within_a_few_megabytes(tmp_path):
    path = tmp_path / "zeros.nc"
    path.write_bytes(b"G1 X1 F100\n" + b"\0" * (8 * MAX_LINE_LENGTH) + b"\n")
    with pytest.raises(GCodeError, match=r"zeros.nc:2: the line is longer than"):
        read_file(path)


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero on this system")
def test_dev_zero_is_refused_not_read_until_memory_runs_out():
    tracemalloc.start()
    try:
        with pytest.raises(GCodeError, match="/dev/zero:1: the line is longer than"):
            read_file("/dev/zero")
        assert tracemalloc.get_traced_memory()[1] < 64 * 2**20
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("options", [{"chord_tolerance": 0}, {"chord_tolerance": -1.0},
                                     {"chord_tolerance": float("nan")}, {"chord_tolerance": float("inf")},
                                     {"initial_motion": 2}])
def test_reader_options_out_of_range_are_refused(options):
    with pytest.raises(ValueError, match=next(iter(options))):
        ReaderOptions(**options)


@pytest.mark.parametrize("value", ["0", "-1", "nan", "inf", "abc"])
def test_cli_chord_tolerance_is_one_line_and_exit_2(tmp_path, value):
    path = tmp_path / "p.nc"
    path.write_text("G1 X1 F100\n")
    done = subprocess.run([sys.executable, "-m", "toolpath.gcode", "--chord-tolerance", value, str(path)],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "is not a length > 0 in mm" in done.stderr.strip().splitlines()[-1]


# --- writer ------------------------------------------------------------------------------------

@pytest.mark.parametrize("value", [float("nan"), float("inf"), -float("inf")])
def test_writer_refuses_non_finite_numbers(value):
    with pytest.raises(ValueError, match="non-finite"):
        fmt(value, 3)
    program = read_text("G1 X0 Y0 F100\nG1 X1 Y0\nG1 X2 Y0\n")
    with pytest.raises(GCodeError, match="non-finite"):
        replace_motion(program, [(2, 3, np.array([[1.0, value], [2.0, 0.0]]))])
    with pytest.raises(ValueError, match="non-finite"):
        fmt_many(np.array([1.0, value]), np.array([3, 3]))


def test_many_numbers_are_written_as_one_at_a_time():
    rng = np.random.default_rng(5)
    values = np.r_[rng.normal(0, 100, 500), -0.0, 0.0, -0.0004, -0.0005, -0.00049999, 0.0005, -0.00005, -1e-12,
                   0.0015, 2.675, -2.675, 1e9, -123.4565]
    decimals = rng.choice([0, 1, 3, 4, 6], len(values))
    expected = [fmt(v, int(d)) for v, d in zip(values.tolist(), decimals.tolist(), strict=True)]
    assert fmt_many(values, decimals) == expected
    assert fmt_many(np.array([-0.0004, -0.0006]), np.array([3, 3])) == ["0.000", "-0.001"]


def test_replacement_keeps_a_lone_cr_line_ending():
    program = read_text("G1 X0 Y0 F100\rG1 X1 Y0\rG1 X2 Y0\r")
    text = replace_motion(program, [(2, 3, np.array([[1.0, 0.5], [2.0, 0.0]]))])
    assert "\n" not in text and read_text(text).points[-1, 0] == 2.0


# --- arbitrary bytes: a program or a GCodeError, in bounded time and memory -----------------------

_WORDS = st.sampled_from(["G0", "G1", "G2", "G3", "G28", "G30.1", "G91", "G92", "G20", "M2", "M30", "M3.5",
                          "X", "Y", "Z", "I", "J", "R", "P", "F", "#1=", "#<a>=", "#1", "[", "]", "**", "/",
                          "-", "(", ")", ";", "%", "\r", "\r\n", "\n", "\ufeff", "\0", "O100", "EXP", "ATAN"])
_NUMBERS = st.one_of(st.integers(-10**12, 10**12).map(str), st.floats(allow_nan=False, allow_infinity=False,
                     min_value=-1e12, max_value=1e12).map(lambda v: f"{v:.4f}"), st.just("9" * 400))
_TEXT = st.lists(st.one_of(_WORDS, _NUMBERS), max_size=60).map("".join)


def _read_bounded(data: bytes, tmp_path) -> None:
    path = tmp_path / "fuzz.nc"
    path.write_bytes(data)
    tracemalloc.start()
    try:
        try:
            program = read_file(path, ReaderOptions(chord_tolerance=0.01))
        except GCodeError as exc:
            assert str(exc).startswith(f"{path}:")
        else:
            assert np.isfinite(program.points).all()
        # arcs are bounded by MAX_ARC_POINTS each: a short program can never ask for gigabytes
        assert tracemalloc.get_traced_memory()[1] < 40 * MAX_ARC_POINTS * 24
    finally:
        tracemalloc.stop()


@settings(max_examples=200, deadline=10_000, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=2000))
def test_arbitrary_bytes_give_a_program_or_a_gcode_error(tmp_path, data):
    _read_bounded(data, tmp_path)


@settings(max_examples=300, deadline=10_000, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.lists(_TEXT, max_size=6).map(" ".join))
def test_arbitrary_gcode_like_text_gives_a_program_or_a_gcode_error(tmp_path, text):
    with contextlib.suppress(UnicodeEncodeError):
        _read_bounded(text.encode("utf-8", "surrogateescape"), tmp_path)


# --- centre-format arcs accepted or refused as LinuxCNC (2.8+) does ----------------------------------

@pytest.mark.parametrize("units, r_start, r_end, accepted", [
    ("G21", 10.0, 10.02, True),      # 0.02 mm <= 2 * 0.01 * sqrt(2) = 0.0283 mm
    ("G21", 10.0, 10.03, False),     # 0.03 mm > 0.0283 and 0.3 % > 0.1 %
    ("G21", 100.0, 100.05, True),    # 0.05 mm > 0.0283 but 0.05 % <= 0.1 %
    ("G21", 5000.0, 5003.0, False),  # 0.06 % but 3 mm > 100 x 0.0283 mm
    ("G21", 2000.0, 2002.0, True),   # 0.1 % and 2 mm <= 2.83 mm
    ("G20", 1.0, 1.002, True),       # inch: 0.002 in <= 2 * 0.001 * sqrt(2) = 0.00283 in
    ("G20", 1.0, 1.003, False),      # 0.003 in > 0.00283 in and 0.3 % > 0.1 %
    ("G20", 0.00004, 0.00004, False),  # below the radius tolerance 0.00005 in: a zero-radius arc
])
def test_centre_arc_radius_tolerances_are_linuxcnc_s(units, r_start, r_end, accepted):
    text = f"{units} G90\nG0 X{r_start:.6f} Y0\nG3 X0 Y{r_end:.6f} I{-r_start:.6f} J0\n"
    if accepted:
        program = read_text(text)
        end = program.points[-1, :2] / (25.4 if units == "G20" else 1.0)
        np.testing.assert_allclose(end, [0.0, r_end], atol=1e-9)
    else:
        with pytest.raises(GCodeError, match="radius") as caught:
            read_text(text)
        assert caught.value.line == 3


@pytest.mark.parametrize("half_chord_excess, accepted", [(0.001, True), (0.002, False)])
def test_r_arc_may_fall_short_of_half_its_chord_by_the_radius_tolerance(half_chord_excess, accepted):
    """LinuxCNC: refused when half the chord exceeds |R| by more than 0.00127 mm (0.00005 in)."""
    text = f"G21 G90\nG0 X0 Y0\nG2 X20 Y0 R{10 - half_chord_excess}\n"
    if accepted:
        assert abs(read_text(text).points[:, 1]).max() == pytest.approx(10.0, abs=0.01)
    else:
        with pytest.raises(GCodeError, match="shorter than half the chord"):
            read_text(text)
