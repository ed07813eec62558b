"""The planner-limit benchmark's two readings against hand-computed trapezoids and toppra's bound."""

import math

import numpy as np
import pytest

from toolpath.bench.planner_limit import lifted, measure, times
from toolpath.corners.path import CornerSettings
from toolpath.feedrate import Machine, polyline_radius

MACHINE = Machine(feed=100.0, period=0.001, chord_error=0.001, contour_error=0.005, normal_acceleration=2000.0,
                  normal_jerk=50000.0, tangential_acceleration=2000.0, tangential_jerk=50000.0, kp=400.0,
                  inertia=0.01, damping=1.0)


def test_without_the_jerk_limit_a_straight_line_is_the_trapezoid_and_the_bound():
    # 10 mm from rest to rest at 100 mm/s, 2000 mm/s^2: 2.5 mm up, 5 mm at the feed, 2.5 mm down
    line = np.column_stack([np.linspace(0.0, 10.0, 11), np.zeros(11)])
    got = times(line, polyline_radius(line, 0.005), MACHINE, straight=True, band=math.inf)
    # (the lifted limit leaves each ramp 1e-9 s of jerk phase)
    assert got["pointwise_without_jerk_limit"] == pytest.approx(0.05 + 0.05 + 5.0 / 100.0, rel=1e-7)
    assert got["toppra_bound"] == pytest.approx(0.15, rel=1e-3)
    # the jerk limit adds A / J to each of the two ramps (S-curves of the same mean acceleration)
    assert got["planner"] == pytest.approx(0.15 + 2000.0 / 50000.0, rel=1e-9)
    assert lifted(MACHINE).tangential_jerk == 2000.0 * 1e9 and lifted(MACHINE).tangential_acceleration == 2000.0


def test_without_the_jerk_limit_a_square_corner_is_two_trapezoids_through_the_vertex_speed():
    corner = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    rho = polyline_radius(corner, 0.005)
    assert rho[1] == pytest.approx(0.005 * math.cos(math.pi / 4) / (1 - math.cos(math.pi / 4)))
    v_c = min(math.sqrt(2000.0 * rho[1]), (rho[1] ** 2 * 50000.0) ** (1 / 3),  # Eq. 19 and 21 bind here
              2 * math.sqrt(2 * rho[1] * 0.001 - 0.001**2) / 0.001)
    A, feed = 2000.0, 100.0
    # each leg: rest <-> feed at the far end, feed <-> v_c at the vertex, the rest at the feed
    up, down = feed / A, (feed - v_c) / A
    leg = up + down + (10.0 - feed**2 / (2 * A) - (feed**2 - v_c**2) / (2 * A)) / feed
    got = times(corner, rho, MACHINE, straight=True, band=math.inf)
    assert got["pointwise_without_jerk_limit"] == pytest.approx(2 * leg, rel=1e-6)
    assert got["toppra_bound"] == pytest.approx(2 * leg, rel=1e-3)
    assert got["planner"] > got["pointwise_without_jerk_limit"]


def test_on_a_smoothed_case_the_pointwise_planner_without_jerk_meets_the_bound_and_g01_is_the_reference():
    out = measure(["w"], CornerSettings(), MACHINE, math.inf, [2000.0], methods=("bezier",))
    rows = out["2000"]["w"]
    assert set(rows) == {"g01", "bezier"}
    for row in rows.values():  # the interval rule and the jerk limit account for the whole gap to the bound
        assert abs(row["pointwise_without_jerk_limit_over_bound_pct"]) < 0.5
        # lifting the jerk limit only shortens ramps; the interval rule against point by point has no order in
        # general (many small S-curves can cost more than one lower speed), so none is asserted
        assert row["pointwise"] > row["pointwise_without_jerk_limit"]
        assert row["planner"] > row["toppra_bound"] and row["pointwise"] > row["toppra_bound"]
    bezier, g01 = rows["bezier"], rows["g01"]
    expected = 100 * (1 - bezier["toppra_bound"] / g01["toppra_bound"])
    assert bezier["saved_vs_g01_pct"]["toppra_bound"] == pytest.approx(expected)
