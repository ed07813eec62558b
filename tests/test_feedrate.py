"""Seed 002's feedrate limits (Eq. 15-22) on hand cases: a circle, a straight line, a square corner."""

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
