"""The NURBS corner paper's feedrate limits (Eq. 15-22) on hand cases: a circle, a straight line, a square corner."""

import math

import numpy as np
import pytest

from toolpath.feedrate import (
    Machine,
    chord_error,
    chord_error_limit,
    contour_error_limit,
    feed_limit,
    normal_acceleration_limit,
    normal_jerk_limit,
    polyline_radius,
)

MACHINE = Machine(feed=100.0, period=0.001, chord_error=0.001, contour_error=0.005, normal_acceleration=2000.0,
                  normal_jerk=50000.0, tangential_acceleration=2000.0, tangential_jerk=50000.0, kp=400.0,
                  inertia=0.01, damping=1.0)


def test_circle_limits_by_hand():
    r = 5.0
    assert normal_acceleration_limit(r, MACHINE) == pytest.approx(math.sqrt(r * 2000.0))  # Eq. 19
    assert normal_jerk_limit(r, MACHINE) == pytest.approx((r * r * 50000.0) ** (1 / 3))  # Eq. 21
    # Eq. 16 and Eq. 15 are inverses: at the chord-error feed the chord error is the limit
    v = chord_error_limit(r, MACHINE)
    assert v == pytest.approx(2 * math.sqrt(2 * r * 0.001 - 0.001**2) / 0.001)
    assert chord_error(v, r, MACHINE.period) == pytest.approx(0.001)


def test_contour_limit_gives_the_contour_error_of_a_second_order_servo():
    """Eq. 17: at v_c the steady-state radius loss rho (1 - |G(j v/rho)|) equals epsilon_lim."""
    for r in (0.5, 5.0, 50.0):
        v = float(contour_error_limit(r, MACHINE))
        wn, zeta, w = MACHINE.natural_frequency, MACHINE.damping_ratio, v / r
        gain = wn**2 / math.sqrt((wn**2 - w**2) ** 2 + (2 * zeta * wn * w) ** 2)
        assert r * (1 - gain) == pytest.approx(MACHINE.contour_error, rel=1e-6)


def test_straight_line_runs_at_the_programmed_feed():
    assert feed_limit(np.array([np.inf]), MACHINE).tolist() == [100.0]  # Eq. 22 capped at the feed
    line = np.column_stack([np.linspace(0, 10, 11), np.zeros(11)])
    assert np.isinf(polyline_radius(line, 0.01)).all()


def test_feed_limit_is_the_least_of_eq_16_to_21():
    rho = np.array([0.01, 0.3, 3.0, 300.0])
    each = np.vstack([chord_error_limit(rho, MACHINE), contour_error_limit(rho, MACHINE),
                      normal_acceleration_limit(rho, MACHINE), normal_jerk_limit(rho, MACHINE),
                      np.full(4, MACHINE.feed)])
    np.testing.assert_allclose(feed_limit(rho, MACHINE), each.min(axis=0))
    assert np.all(np.diff(feed_limit(rho, MACHINE)) >= 0)  # flatter is faster


def test_polyline_radius_of_a_discretised_circle_and_a_square_corner():
    k, r = 72, 20.0
    a = np.linspace(0, 2 * np.pi, k + 1)
    circle = np.column_stack([r * np.cos(a), r * np.sin(a)])
    # with a tolerance above the chords' sagitta (0.019 mm) the half-segment bound gives R cos(pi/k) ...
    np.testing.assert_allclose(polyline_radius(circle, 0.05)[1:-1], r * np.cos(np.pi / k), rtol=1e-9)
    # ... below it, the blend must stay closer to the vertex than the circle does: a tighter radius
    assert (polyline_radius(circle, 0.01)[1:-1] < r / 1.5).all()
    corner = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    tol = 0.01  # a 90 degree turn: the blend arc within tol of the corner has radius tol cos45 / (1 - cos45)
    assert polyline_radius(corner, tol)[1] == pytest.approx(tol * math.cos(math.pi / 4) / (1 - math.cos(math.pi / 4)))
    short = np.array([[0.0, 0.0], [0.02, 0.0], [0.02, 0.02]])  # then half a segment bounds the arc
    assert polyline_radius(short, 1.0)[1] == pytest.approx(0.01)
    assert polyline_radius(np.array([[0, 0], [1, 0], [0, 0]], dtype=float), 0.01)[1] < 1e-12  # reversal: stop


# --- the planner: sensitive / non-sensitive intervals, S-curve ramps ---------------------------------

from toolpath.feedrate.bounds import stop_at_every_vertex_time, toppra_time  # noqa: E402
from toolpath.feedrate.planner import arc_length, plan  # noqa: E402
from toolpath.feedrate.scurve import ramp_distance, ramp_samples, ramp_time  # noqa: E402


def test_s_curve_ramp_reaches_its_speed_within_the_acceleration_and_jerk_limits():
    A, J = MACHINE.tangential_acceleration, MACHINE.tangential_jerk
    for v0, v1 in ((0.0, 100.0), (100.0, 20.0), (10.0, 12.0)):
        t, s, v, a, j = ramp_samples(v0, v1, A, J, 1e-4)
        assert v[0] == pytest.approx(v0) and v[-1] == pytest.approx(v1, abs=1e-9)
        assert a[0] == 0.0 and a[-1] == pytest.approx(0.0, abs=1e-9)
        assert np.abs(a).max() <= A + 1e-9 and np.abs(j).max() <= J
        assert t[-1] == pytest.approx(ramp_time(v0, v1, A, J)) and s[-1] == pytest.approx(ramp_distance(v0, v1, A, J))
    # by hand: 0 -> 100 mm/s with A = 2000, J = 50000: t_j = 0.04 s, t_a = 0.01 s, 0.09 s and 4.5 mm
    assert ramp_time(0.0, 100.0, A, J) == pytest.approx(0.09) and ramp_distance(0.0, 100.0, A, J) == pytest.approx(4.5)


def _limits_hold(p, points, rho):
    vertex_speed = np.interp(arc_length(points), p.s, p.v)
    assert np.all(vertex_speed <= feed_limit(rho, MACHINE) * (1 + 1e-6) + 1e-9)
    assert np.all(chord_error(vertex_speed, rho, MACHINE.period) <= MACHINE.chord_error * (1 + 1e-6))
    assert np.abs(p.a).max() <= MACHINE.tangential_acceleration + 1e-6
    assert np.abs(p.j).max() <= MACHINE.tangential_jerk + 1e-6
    assert p.v.min() >= -1e-9 and p.v[0] == 0.0 and p.v[-1] == pytest.approx(0.0, abs=1e-9)
    assert p.s[-1] == pytest.approx(arc_length(points)[-1], rel=1e-9)


def test_a_straight_line_runs_at_the_programmed_feed():
    points = np.array([[0.0, 0.0], [50.0, 0.0], [100.0, 0.0]])
    p = plan(points, polyline_radius(points, 0.01), MACHINE)
    assert p.v.max() == pytest.approx(MACHINE.feed)
    expected = 2 * ramp_time(0, 100, 2000, 50000) + (100.0 - 2 * 4.5) / 100.0
    assert p.time == pytest.approx(expected)
    _limits_hold(p, points, polyline_radius(points, 0.01))


def test_a_circle_runs_at_its_curvature_limit():
    r = 2.0
    angle = np.linspace(0, 2 * np.pi, 2001)
    points = np.c_[r * np.cos(angle), r * np.sin(angle)]
    rho = np.full(len(points), r)  # the analytic curvature of the circle
    p = plan(points, rho, MACHINE, straight=False)
    cruise = p.v[len(p.v) // 2]
    assert cruise == pytest.approx(float(feed_limit(r, MACHINE)))
    assert cruise < MACHINE.feed
    _limits_hold(p, points, rho)


def test_square_corner_slows_down_and_the_time_lies_between_the_bounds():
    points = np.array([[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0]])
    rho = polyline_radius(points, 0.01)
    p = plan(points, rho, MACHINE)
    _limits_hold(p, points, rho)
    corner = np.interp(40.0, p.s, p.v)
    assert corner == pytest.approx(float(feed_limit(rho[1], MACHINE)), rel=1e-6)
    lower, upper = toppra_time(points, rho, MACHINE), stop_at_every_vertex_time(points, MACHINE)
    assert lower <= p.time <= upper
    straight = plan(np.array([[0.0, 0.0], [120.0, 0.0]]), np.full(2, np.inf), MACHINE)
    assert p.time > straight.time  # same length, the corners cost time


def test_a_sharp_corner_next_to_the_start_lowers_the_speed_until_the_ramp_fits():
    """The first segment is 0.2 mm: too short to reach the corner's limit from rest."""
    points = np.array([[0.0, 0.0], [0.2, 0.0], [0.2, 30.0], [10.0, 30.0], [10.0, 30.3]])
    rho = polyline_radius(points, 0.05)
    p = plan(points, rho, MACHINE)
    _limits_hold(p, points, rho)
    first = p.intervals[0]
    assert first.speed <= ramp_reachable(0.2) + 1e-9


def ramp_reachable(length):
    lo, hi = 0.0, MACHINE.feed
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if ramp_distance(0.0, mid, 2000.0, 50000.0) <= length else (lo, mid)
    return lo


def test_the_planner_lies_between_the_bounds_on_a_smooth_curve_and_a_rough_polyline():
    rng = np.random.default_rng(3)
    angle = np.linspace(0, np.pi, 400)
    arc = np.c_[3 * np.cos(angle), 3 * np.sin(angle)]  # a half circle, analytic curvature
    p = plan(arc, np.full(len(arc), 3.0), MACHINE, straight=False)
    assert toppra_time(arc, np.full(len(arc), 3.0), MACHINE, straight=False) <= p.time * (1 + 1e-6)
    assert p.time <= stop_at_every_vertex_time(arc, MACHINE)
    rough = np.c_[np.linspace(0, 20, 50), 0.05 * rng.standard_normal(50)]  # a G01 path with noise
    rho = polyline_radius(rough, 0.01)
    p = plan(rough, rho, MACHINE)
    _limits_hold(p, rough, rho)
    assert toppra_time(rough, rho, MACHINE) <= p.time * (1 + 1e-6) <= stop_at_every_vertex_time(rough, MACHINE)


def test_bands_split_a_curve_of_varying_curvature_and_save_time():
    """The paper runs a whole sensitive run at its lowest limit; bands (beyond the paper) do not."""
    t = np.linspace(0.0, 1.0, 600)
    spiral = np.c_[(1 + 9 * t) * np.cos(3 * np.pi * t), (1 + 9 * t) * np.sin(3 * np.pi * t)]
    rho = _discrete_radius(spiral)
    paper = plan(spiral, rho, MACHINE, straight=False)
    banded = plan(spiral, rho, MACHINE, straight=False, band=0.1)
    assert len(banded.intervals) > len(paper.intervals)
    assert toppra_time(spiral, rho, MACHINE, straight=False) <= banded.time * (1 + 1e-6) < paper.time
    _limits_hold(banded, spiral, rho)


def _discrete_radius(points):
    """Radius of the circle through each point and its two neighbours (inf at the ends)."""
    a, b, c = points[:-2], points[1:-1], points[2:]
    ab, bc, ca = (np.linalg.norm(x - y, axis=1) for x, y in ((a, b), (b, c), (c, a)))
    cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    return np.concatenate([[np.inf], ab * bc * ca / (2 * cross), [np.inf]])


def test_chord_limit_on_a_radius_below_the_chord_tolerance_keeps_the_chord_within_the_diameter():
    """Eq. 16 alone would give 0 below rho = Delta / 2; the chord error there is at most rho < Delta."""
    for rho in (0.0002, 0.0005, 0.001):
        v = float(chord_error_limit(rho, MACHINE))
        assert v == pytest.approx(2 * rho / MACHINE.period) and v > 0
        assert chord_error(v, rho, MACHINE.period) <= MACHINE.chord_error
    above = float(chord_error_limit(0.001 * (1 + 1e-9), MACHINE))
    assert above == pytest.approx(float(chord_error_limit(0.001, MACHINE)), rel=1e-6)  # continuous at Delta


def test_a_cusp_along_a_smooth_curve_is_refused_with_a_message():
    points = np.c_[np.linspace(0, 1, 11), np.zeros(11)]
    rho = np.full(11, np.inf)
    rho[4:7] = 0.0
    with pytest.raises(ValueError, match="cusp"):
        plan(points, rho, MACHINE, straight=False)
