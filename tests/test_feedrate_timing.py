"""The vectorised machining time of ``toolpath smooth`` against the interval planner it stands in for."""

from __future__ import annotations

import numpy as np
import pytest

from toolpath.feedrate import Machine, plan, polyline_radius
from toolpath.feedrate.planner import _vertex_intervals, arc_length
from toolpath.feedrate.scurve import ramp_distance as scalar_ramp_distance
from toolpath.feedrate.timing import fit_speeds, machining_time, ramp_distance, vertex_intervals

MACHINE = Machine(feed=100.0, period=0.001, chord_error=0.001, contour_error=0.005, normal_acceleration=2000.0,
                  normal_jerk=50000.0, tangential_acceleration=2000.0, tangential_jerk=50000.0, kp=400.0,
                  inertia=0.01, damping=1.0)


def test_a_straight_line_is_a_ramp_up_a_cruise_and_a_ramp_down():
    # 10 mm at 100 mm/s, A = 2000, J = 50000: dv = 100 >= A^2/J = 80, so a ramp takes A/J + dv/A = 0.09 s
    # and covers 0.5 * 100 * 0.09 = 4.5 mm; two ramps 9 mm, cruise 1 mm in 0.01 s: 0.19 s in all
    line = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    assert machining_time(line, MACHINE, 0.005) == pytest.approx(0.19, rel=1e-12)


def test_ramp_distance_is_the_scalar_planner_s():
    v0, v1 = np.array([0.0, 10.0, 60.0, 99.0]), np.array([100.0, 20.0, 100.0, 100.0])
    expected = [scalar_ramp_distance(a, b, 2000.0, 50000.0) for a, b in zip(v0, v1, strict=True)]
    assert ramp_distance(v0, v1, 2000.0, 50000.0) == pytest.approx(expected, rel=1e-15)


@pytest.mark.parametrize("noise, rel", [(0.0, 1e-8), (0.002, 1e-8), (0.01, 1e-8), (0.05, 1e-8), (0.3, 1e-5)])
def test_the_time_is_the_planner_s(noise, rel):
    rng = np.random.default_rng(3)
    s = np.arange(600) * 0.2
    points = np.c_[50 * np.cos(s / 40), 50 * np.sin(s / 40)] + rng.normal(0, noise, (600, 2))
    points[250] += [0.5, 0.0]  # a sharp spike
    expected = plan(points, polyline_radius(points, 0.005), MACHINE).time
    assert machining_time(points, MACHINE, 0.005) == pytest.approx(expected, rel=rel)


def test_a_square_s_corners_are_intervals_of_their_own():
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], float)
    s, limit = arc_length(square), np.array([100.0, 5.0, 5.0, 5.0, 100.0])
    start, end, speed, sensitive = vertex_intervals(s, limit, 100.0)
    expected = _vertex_intervals(s, limit, 100.0)
    assert [tuple(x) for x in zip(start, end, speed, sensitive, strict=True)] == expected
    assert machining_time(square, MACHINE, 0.005) == pytest.approx(
        plan(square, polyline_radius(square, 0.005), MACHINE).time, rel=1e-12)


@pytest.mark.parametrize("count", [1, 2, 3, 4, 7, 8])
def test_a_last_interval_lowered_beside_the_rest_at_the_end_is_the_last(count):
    # intervals as :func:`vertex_intervals` makes them (segments between vertices of their own, of
    # length 0), ending on a vertex: it is lowered to rest beside the path's end, which is no interval
    # (with an even count that once read past the end of the speeds)
    lengths, limits = np.tile([0.01, 0.0], count), np.tile([100.0, 50.0], count)
    speeds = fit_speeds(lengths, limits, MACHINE)
    around = np.r_[0.0, speeds, 0.0]
    A, J = MACHINE.tangential_acceleration, MACHINE.tangential_jerk
    for k in range(len(lengths)):
        need = sum(float(ramp_distance(np.array([v]), np.array([speeds[k]]), A, J)[0])
                   for v in (around[k], around[k + 2]) if v < speeds[k])
        assert need <= lengths[k] * (1 + 1e-9) + 1e-12
    assert speeds[-1] == 0.0 and (speeds[:-1] > 0).all()
