"""NURBS blocks, G6.2 and LinuxCNC's G5.2 / G5.3: hand cases (Bezier arcs, an exact quarter circle),
errors with their lines, and the same points whether a program is read whole, line by line or in parts."""

from __future__ import annotations

import numpy as np
import pytest

from toolpath.gcode import GCodeError, ReaderOptions, read_text
from toolpath.gcode.program import Motion
from toolpath.gcode.reading import Reading

BEZIER = """G21 G90
G0 X0 Y0
G6.2 P3 K0 X0 Y0 R1 F500
K0 X0 Y5 R1
K0 X5 Y5 R1
K1
K1
K1
G1 X10 Y5
M30
"""


def _bezier(t):
    p = np.array([[0.0, 0.0], [0.0, 5.0], [5.0, 5.0]])
    return ((1 - t) ** 2)[:, None] * p[0] + (2 * t * (1 - t))[:, None] * p[1] + (t ** 2)[:, None] * p[2]


def _distance_to_polyline(points, polyline):
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    t = np.clip(np.einsum("kij,ij->ki", points[:, None] - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    return np.linalg.norm(points[:, None] - (a + t[..., None] * ab), axis=2).min(axis=1)


def test_a_quadratic_block_is_its_bezier_within_the_chord_tolerance():
    p = read_text(BEZIER, options=ReaderOptions(chord_tolerance=0.001))
    curve = p.points[p.kinds == Motion.ARC][:, :2]
    assert np.allclose(curve[-1], [5.0, 5.0]) and np.array_equal(p.points[-1], [10.0, 5.0, 0.0])
    # every chord end lies on the curve: the point of the Bezier nearest to it is within rounding
    dense = _bezier(np.linspace(0, 1, 20001))
    assert _distance_to_polyline(curve, dense).max() < 1e-6
    # and the curve lies within the chord tolerance of the chords (the start point joins them)
    chords = np.vstack([[0.0, 0.0], curve])
    assert _distance_to_polyline(dense, chords).max() <= 0.001 + 1e-9
    assert set(p.lines_of_points[p.kinds == Motion.ARC]) == {8}  # the block's last K line
    assert p.states[8].position == (5.0, 5.0, 0.0) and p.states[8].feed == 500.0


def test_a_rational_quadratic_draws_an_exact_quarter_circle():
    w = np.sqrt(0.5)
    text = f"G0 X10 Y0\nG6.2 P3 K0 X10 Y0 R1\nK0 X10 Y10 R{w:.15f}\nK0 X0 Y10 R1\nK1\nK1\nK1\n"
    p = read_text(text, options=ReaderOptions(chord_tolerance=0.002))
    curve = p.points[1:, :2]
    assert np.abs(np.hypot(curve[:, 0], curve[:, 1]) - 10.0).max() < 1e-9
    chords = np.vstack([[10.0, 0.0], curve])
    middle = 0.5 * (chords[1:] + chords[:-1])
    assert (10.0 - np.hypot(middle[:, 0], middle[:, 1])).max() <= 0.002  # each chord's sagitta


@pytest.mark.parametrize("block, line, fragment", [
    ("G6.2 P3 K0 X0 Y0\nK0 X0 Y5\nK0 X5 Y5\nK1\nK1\nG1 X9\n", 6, "needs 6 knots"),
    ("G6.2 P3 K0 X0 Y0\nK1 X0 Y5\nK0 X5 Y5\nK1\nK1\nK1\nG1 X9\n", 7, "must not decrease"),
    ("G6.2 P3 K0 X1 Y0\n", 2, "is not where the tool stands"),
    ("G91\nG6.2 P3 K0 X0 Y0\n", 3, "absolute coordinates"),
    ("G6.2 K0 X0 Y0\n", 2, "needs P"),
    ("G6.2 P3 K0 X0 Y0\nK0 X0 Y5 M3\n", 3, "only K, X, Y, Z, R"),
    ("G6.2 P3 K0 X0 Y0\nK0 X0 Y5 R0\n", 3, "must be positive"),
    ("G6.2 P3 K0 X0 Y0\nK0 X0 Y5\nK0 X5 Y5\nK1\nK1\nK1\nX9\n", 8, "no motion mode in effect"),
    ("G6.1 X1\n", 2, "only G6.2"),
    ("G5.2 X1 Y2\nX2 Y0\n", 2, "not closed by G5.3"),
    ("G5.3\n", 2, "G5.3 without a G5.2"),
    ("G5.2 X1 Y2\nX2 Y0 Z1\nG5.3\n", 3, "XY plane"),
    ("G5.2 X1 Y2\nX2 Y0 M3\nG5.3\n", 3, "only X, Y, P"),
    ("G5.2 X1 Y2\nG1 X2 Y0\nG5.3\n", 3, "G1"),
    ("G5.2 X1 Y2 L11\nX2 Y0\nG5.3\n", 2, "whole number 2-10"),
    ("G5.2 X1 Y2 L4\nX2 Y0\nG5.3\n", 4, "at least 4 control points"),
    ("G5.2 X1 Y2\nX2 Y0 P0\nG5.3\n", 3, "must be positive"),
    ("G5.2 X1 Y2\nX2 Y0\nG5.3 X4\n", 4, "line of its own"),
    ("G91\nG5.2 X1 Y2\n", 3, "absolute coordinates"),
    ("G5.2 X1 Y2\nX2 Y0\nG5.3\nX9\n", 5, "no motion mode in effect"),
    ("G5.1 X1 I1 J1\n", 2, "only G5.2 / G5.3"),
])
def test_a_bad_block_is_refused_with_its_line(block, line, fragment):
    with pytest.raises(GCodeError, match=fragment) as caught:
        read_text("G0 X0 Y0\n" + block, "part.nc")
    assert f"part.nc:{line}:" in str(caught.value)


def test_a_block_at_the_end_of_the_program_is_closed_there():
    p = read_text("G0 X0 Y0\nG6.2 P2 K0 X0 Y0\nK0 X3 Y4\nK1\nK1\n")
    assert np.array_equal(p.points[-1], [3.0, 4.0, 0.0]) and p.kinds[-1] == Motion.ARC


def test_blocks_read_the_same_whole_line_by_line_and_in_parts():
    text = BEZIER.replace("M30\n", "") + "G0 X0 Y0\n" + BEZIER.split("\n", 2)[2]
    whole, slow = read_text(text), read_text(text, vectorise=False)
    assert whole.points.tobytes() == slow.points.tobytes()
    lines = text.splitlines(keepends=True)
    reading = Reading()
    first = reading.read("".join(lines[:5]), final=False)  # ends inside the first block
    rest = reading.read("".join(lines[5:]))
    joined = first.then(rest)
    assert joined.points.tobytes() == whole.points.tobytes()
    assert np.array_equal(joined.lines_of_points, whole.lines_of_points)


# --- G5.2 / G5.3, LinuxCNC's form ---------------------------------------------------------------

LINUXCNC = """G21 G90
G0 X0 Y0
F10
G5.2 X1 Y2 L3
     X2 Y0
G5.3
G1 X3
M2
"""


def test_a_g5_2_block_of_three_points_is_its_quadratic_bezier():
    # three control points of order 3: knots 0 0 0 1 1 1, the Bezier x = 2t, y = 4t(1 - t), i.e.
    # the parabola y = 2x - x^2 from (0, 0) through its top (1, 1) to (2, 0)
    p = read_text(LINUXCNC, options=ReaderOptions(chord_tolerance=0.001))
    curve = p.points[p.kinds == Motion.ARC][:, :2]
    assert np.abs(curve[:, 1] - (2 * curve[:, 0] - curve[:, 0] ** 2)).max() < 1e-12
    assert np.allclose(curve[-1], [2.0, 0.0]) and abs(curve[:, 1].max() - 1.0) < 1e-3
    chords = np.vstack([[0.0, 0.0], curve])
    x = np.linspace(0, 2, 20001)
    assert _distance_to_polyline(np.c_[x, 2 * x - x ** 2], chords).max() <= 0.001 + 1e-9
    assert set(p.lines_of_points[p.kinds == Motion.ARC]) == {6}  # the G5.3 line runs the curve
    assert p.states[6].position == (2.0, 0.0, 0.0) and p.states[5].position == (0.0, 0.0, 0.0)
    assert np.array_equal(p.points[-1], [3.0, 0.0, 0.0]) and p.states[7].feed == 10.0


def test_the_linuxcnc_knots_and_weights():
    from toolpath.gcode.nurbs import linuxcnc_knots

    # nurbs_G5_knot_vector_creator: 5 control points (n = 4), order 3 -> 0 0 0 1 2 3 3 3
    assert linuxcnc_knots(5, 3) == [0, 0, 0, 1, 2, 3, 3, 3] and linuxcnc_knots(2, 2) == [0, 0, 1, 1]
    # weights: the same quarter circle as G6.2's, the first weight from a G5.2 line without X, Y
    w = np.sqrt(0.5)
    text = f"G0 X10 Y0\nG5.2 P1\nX10 Y10 P{w:.15f}\nX0 Y10 P1\nG5.3\n"
    curve = read_text(text, options=ReaderOptions(chord_tolerance=0.002)).points[1:, :2]
    assert np.abs(np.hypot(curve[:, 0], curve[:, 1]) - 10.0).max() < 1e-9 and np.allclose(curve[-1], [0, 10])


def test_g5_2_blocks_read_the_same_whole_line_by_line_and_in_parts(tmp_path):
    from toolpath.models.rule import LocalCurvatureRule
    from toolpath.smooth.command import DISPATCH, SMOOTHING
    from toolpath.smooth.rewrite import RewriteOptions
    from toolpath.smooth.stream import smooth_parts

    text = LINUXCNC.replace("M2\n", "") + "G0 X0 Y0\n" + LINUXCNC.split("\n", 2)[2]
    whole, slow = read_text(text), read_text(text, vectorise=False)
    assert whole.points.tobytes() == slow.points.tobytes()  # the plain X Y lines are control points
    lines = text.splitlines(keepends=True)
    for cut in range(1, len(lines)):
        reading = Reading()
        joined = reading.read("".join(lines[:cut]), final=False).then(reading.read("".join(lines[cut:])))
        assert joined.points.tobytes() == whole.points.tobytes()
    # toolpath smooth in parts of a few bytes: the block is never cut, the output is the input
    path = tmp_path / "g5.ngc"
    path.write_text(text)
    options = RewriteOptions(tolerance=0.01, smoothing=SMOOTHING, mapping=DISPATCH)
    parts = list(smooth_parts(path, LocalCurvatureRule().predict, options, part_bytes=20))
    assert "".join(part.result.text for part in parts) == text


def test_spline_evaluation_agrees_with_scipys_bspline():
    """The reader evaluates NURBS with its own de Boor (reading G-code needs no SciPy): within 1e-12 of
    scipy's BSpline on random clamped knot vectors, degrees 1-5, interior knots repeated up to the degree."""
    from collections import Counter

    from scipy.interpolate import BSpline

    from toolpath.gcode.nurbs import evaluate_spline

    rng = np.random.default_rng(3)
    checked = 0
    while checked < 300:
        k = int(rng.integers(1, 6))
        n = int(rng.integers(k + 1, 14))
        inner = np.sort(rng.integers(1, 5, n - k - 1).astype(float) if checked % 2 else rng.random(n - k - 1) * 4.8)
        if any(count > k for count in Counter(inner.tolist()).values()):
            continue
        knots = np.concatenate([np.zeros(k + 1), inner, np.full(k + 1, 5.0)])
        coefficients = rng.normal(size=(n, 4)) * 10
        t = np.concatenate([np.linspace(0.0, 5.0, 41), inner])
        expected = BSpline(knots, coefficients, k, extrapolate=False)(t)
        np.testing.assert_allclose(evaluate_spline(knots, coefficients, k, t), expected, rtol=0, atol=1e-12 * 60)
        checked += 1


def test_g62_repeated_on_the_block_lines_reads_as_the_block_without_it():
    """LinuxCNC's G6.2 examples repeat G6.2 on control-point and closing-knot lines (``G6.2 K1``): modal,
    the same curve; a G6.2 line with P after a complete block starts the next block."""
    lines = BEZIER.splitlines()
    repeated = "\n".join(f"G6.2 {line}" if line.startswith("K") else line for line in lines) + "\n"
    plain, again = read_text(BEZIER), read_text(repeated)
    assert np.array_equal(plain.points, again.points) and np.array_equal(plain.kinds, again.kinds)
    two = BEZIER.replace("G1 X10 Y5\n", "G6.2 P2 K0 X5 Y5\nK0 X8 Y5\nK1\nK1\n")
    both = read_text(two)
    assert np.allclose(both.points[-1], [8.0, 5.0, 0.0]) and both.states[12].position == (8.0, 5.0, 0.0)


@pytest.mark.parametrize("line", ["G6.2 G1 K1", "G5.2 K1"])
def test_a_block_line_with_another_g_code_names_it(line):
    text = BEZIER.replace("K1\nK1\nK1\n", f"K1\nK1\n{line}\n")
    with pytest.raises(GCodeError, match=r":8: a G6.2 block line holds only .*not G"):
        read_text(text, source="p.nc")
