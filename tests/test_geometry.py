"""Hand-computed cases for Eq. 1-3 and 8-10, arc length and deviation."""

import math

import numpy as np
import pytest

from toolpath.geometry import (
    arc_length,
    drop_repeated,
    fitness,
    hausdorff,
    local_curvature,
    point_to_polyline,
    smoothness_penalty,
    turning_cosines,
)


def plain_local_curvature(points):
    """Eq. 3 term by term in plain Python, as written in the paper."""
    total = 0.0
    for i in range(1, len(points) - 1):
        v0 = (points[i][0] - points[i - 1][0], points[i][1] - points[i - 1][1])
        v1 = (points[i + 1][0] - points[i][0], points[i + 1][1] - points[i][1])
        dot = v1[0] * v0[0] + v1[1] * v0[1]
        total += 1.0 - dot / (math.hypot(*v1) * math.hypot(*v0))
    return total


def test_straight_line_has_zero_curvature():
    line = np.column_stack([np.linspace(0, 10, 50), np.linspace(0, 3, 50)])
    assert local_curvature(line) == pytest.approx(0.0, abs=1e-12)


def test_one_right_angle_corner_counts_one():
    corner = np.array([[0, 0], [1, 0], [2, 0], [2, 1], [2, 2]], dtype=float)
    assert local_curvature(corner) == pytest.approx(1.0)


def test_reduction_of_a_square_corner_rounded_to_two_half_turns():
    from toolpath.geometry.curvature import reduction_pct

    square = np.array([[0, 0], [1, 0], [1, 1]], dtype=float)  # one right angle: 1
    chamfered = np.array([[0, 0], [0.5, 0], [1, 0.5], [1, 1]], dtype=float)  # two 45-degree turns
    after = local_curvature(chamfered)
    assert after == pytest.approx(2 * (1 - math.cos(math.pi / 4)))
    assert reduction_pct(local_curvature(square), after) == pytest.approx(100 * (1 - 2 + math.sqrt(2)))
    assert reduction_pct(0.0, 0.0) == 0.0  # a straight window has nothing to remove


def test_reversal_counts_two():
    back = np.array([[0, 0], [1, 0], [0, 0]], dtype=float)
    assert local_curvature(back) == pytest.approx(2.0)


@pytest.mark.parametrize("sides", [3, 4, 6, 12])
def test_regular_polygon_closed_form(sides):
    k = np.arange(50)
    ang = 2 * np.pi * k / sides
    pts = np.column_stack([np.cos(ang), np.sin(ang)])
    expected = 48 * (1 - np.cos(2 * np.pi / sides))  # 48 vertices, each turning 2 pi / sides
    assert local_curvature(pts) == pytest.approx(expected)


def test_window_of_50_points_has_48_terms():
    pts = np.random.default_rng(0).normal(size=(50, 2))
    assert turning_cosines(pts).shape == (48,)


def test_batched_matches_plain_python_on_random_windows():
    rng = np.random.default_rng(1)
    batch = rng.normal(size=(20, 50, 2)).cumsum(axis=1)
    got = local_curvature(batch)
    assert got.shape == (20,)
    for k in range(20):
        assert got[k] == pytest.approx(plain_local_curvature(batch[k].tolist()), rel=1e-12)


def test_zero_length_segment_gives_no_nan_and_drop_repeated_removes_it():
    pts = np.array([[0, 0], [1, 0], [1, 0], [2, 0]], dtype=float)
    assert np.isfinite(local_curvature(pts))
    kept, mask = drop_repeated(pts)
    assert kept.tolist() == [[0, 0], [1, 0], [2, 0]]
    assert mask.tolist() == [True, True, False, True]


def test_smoothness_penalty_of_square_corner():
    # second differences: (1,0)-(0,0)... at the corner point (1,0): (1,1) - 2(1,0) + (0,0) = (-1, 1)
    pts = np.array([[0, 0], [1, 0], [1, 1]], dtype=float)
    assert smoothness_penalty(pts) == pytest.approx(math.sqrt(2))
    assert fitness(pts) == pytest.approx(1.0 + math.sqrt(2))


def test_smoothness_penalty_of_evenly_spaced_line_is_zero():
    assert smoothness_penalty(np.column_stack([np.arange(10.0), 2 * np.arange(10.0)])) == pytest.approx(0)


def test_arc_length_of_discretised_circle_approaches_circumference():
    t = np.linspace(0, 2 * np.pi, 2001)
    circle = 3.0 * np.column_stack([np.cos(t), np.sin(t)])
    assert arc_length(circle) == pytest.approx(2 * np.pi * 3.0, rel=1e-5)


def test_point_to_polyline_and_symmetric_deviation():
    square_side = np.array([[0, 0], [10, 0]], dtype=float)
    pts = np.array([[5, 2], [-3, 4], [12, 0]], dtype=float)
    assert point_to_polyline(pts, square_side).tolist() == pytest.approx([2.0, 5.0, 2.0])
    bump = np.array([[0, 0], [5, 0.3], [10, 0]], dtype=float)
    assert hausdorff(bump, square_side) == pytest.approx(0.3)
    # symmetric: a short path is close to the long one, but not the other way round
    short = np.array([[0, 0], [2, 0]], dtype=float)
    assert hausdorff(short, square_side) == pytest.approx(8.0)


def test_deviation_is_batched():
    a = np.zeros((4, 5, 2))
    b = a.copy()
    b[:, 2, 1] = np.arange(4)
    assert hausdorff(a, b).tolist() == pytest.approx([0, 1, 2, 3])
