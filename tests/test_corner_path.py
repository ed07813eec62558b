"""Whole-path corner smoothing (issue 9): the comparison transitions, the case paths, plan checks."""

import math

import numpy as np
import pytest

from toolpath.corners.cases import CASES, case_path
from toolpath.corners.path import CornerSettings, corner_frames, corner_smoother, smooth_path
from toolpath.corners.pso import PsoSettings
from toolpath.corners.transitions import bezier_curve, bezier_transition, bspline_transition
from toolpath.feedrate import Machine
from toolpath.feedrate.assess import assess
from toolpath.feedrate.limits import polyline_radius
from toolpath.feedrate.scurve import ramp_distance, ramp_time
from toolpath.geometry.deviation import point_to_polyline

MACHINE = Machine(feed=100.0, period=0.001, chord_error=0.001, contour_error=0.005, normal_acceleration=2000.0,
                  normal_jerk=50000.0, tangential_acceleration=2000.0, tangential_jerk=50000.0, kp=400.0,
                  inertia=0.01, damping=1.0)
SQUARE = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
FAST = CornerSettings(pso=PsoSettings(particles=10, iterations=10, seed=3))


def test_bspline_transition_meets_delta_max_exactly_or_fills_its_room():
    turn = math.radians(90)
    roomy = bspline_transition(turn, room=10.0, delta_max=0.1)
    assert max(roomy.delta_1, roomy.delta_2) == pytest.approx(0.1, rel=1e-9)  # deviation is linear in the leg
    assert np.isinf(roomy.curve.radius(np.array([0.0, 1.0]))).all()  # P_{i-2}, P_{i-1}, P_i collinear: G2 ends
    tight = bspline_transition(turn, room=0.2, delta_max=0.1)
    assert np.linalg.norm(tight.curve.points[0]) == pytest.approx(0.2)  # reaches exactly the room
    assert max(tight.delta_1, tight.delta_2) < 0.1


def test_dual_bezier_is_g2_and_matches_the_bezier_formula():
    turn, span, k = math.radians(90), 2.0, 0.4
    found = bezier_curve(turn, span, k, delta_max=1.0)
    b = found.curve.points
    # the first piece at its middle (u = 1/4): (B0 + 3 B1 + 3 B2 + B3) / 8
    np.testing.assert_allclose(found.curve(0.25)[0], (b[0] + 3 * b[1] + 3 * b[2] + b[3]) / 8, atol=1e-12)
    np.testing.assert_allclose(found.curve(0.5)[0], b[3], atol=1e-12)  # the apex is B3 on the bisector
    assert b[3][0] == 0 and found.delta_2 == pytest.approx(k * span * math.cos(math.pi / 4))
    rho = found.curve.radius(np.array([0.0, 0.5 - 1e-7, 0.5 + 1e-7, 1.0]))
    assert np.isinf(rho[[0, 3]]).all()  # zero curvature where the lines end
    assert rho[1] == pytest.approx(rho[2], rel=1e-5)  # equal curvature on both sides of the joint
    best = bezier_transition(turn, room=10.0, delta_max=0.1)
    assert best.feasible and best.delta_2 == pytest.approx(0.1, rel=1e-6)
    assert best.max_curvature <= bezier_curve(turn, 0.1 / (0.2 * math.cos(math.pi / 4)), 0.2, 0.1).max_curvature


def test_corner_frames_of_a_square_corner():
    (vertex, corner, frame), = corner_frames(SQUARE, CornerSettings())
    assert vertex == 1 and math.degrees(corner.turn) == pytest.approx(90) and corner.leg == pytest.approx(2.5)
    start = corner.leg_point(2 * corner.leg, -1)  # P_{i-2} in the frame lies on the incoming segment
    np.testing.assert_allclose(SQUARE[1] + frame @ start, [5.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(SQUARE[1] + frame @ corner.leg_point(2 * corner.leg, 1), [10.0, 5.0], atol=1e-12)
    assert corner_frames(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.1]]), CornerSettings()) == []  # 5.7 deg


@pytest.mark.parametrize("method", ["bspline", "bezier", "nurbs_pso"])
def test_smoothed_square_corner_stays_within_delta_max(method):
    smoothed = smooth_path(SQUARE, corner_smoother(method), FAST)
    np.testing.assert_allclose(smoothed.points[[0, -1]], SQUARE[[0, -1]])
    assert point_to_polyline(smoothed.points, SQUARE).max() <= 0.1 + 1e-9
    (result,) = smoothed.corners
    assert not result.source.startswith("kept") and result.error <= 0.1 + 1e-9
    # 'before' is the arc blend within delta_max: radius delta cos45 / (1 - cos45)
    assert result.curvature_before == pytest.approx((1 - math.cos(math.pi / 4)) / (0.1 * math.cos(math.pi / 4)))
    assert np.all(np.diff(np.linalg.norm(np.diff(smoothed.points, axis=0), axis=1)) < 1.0)  # no gaps


def test_net_method_needs_networks():
    with pytest.raises(ValueError, match="FDLS"):
        corner_smoother("nurbs_net")
    with pytest.raises(ValueError, match="unknown corner method"):
        corner_smoother("spline")


def test_case_paths_have_the_character_the_paper_gives():
    turns = {name: [math.degrees(c.turn) for _, c, _ in corner_frames(case_path(name), CornerSettings())]
             for name in CASES}
    assert len(turns["w"]) == 5
    dress = case_path("dress")
    np.testing.assert_allclose(dress[0], dress[-1])  # closed
    mirrored = dress * [-1.0, 1.0]
    assert point_to_polyline(mirrored, dress).max() < 1e-9  # symmetric about x = 0
    small = [t for t in np.degrees(np.arccos(np.clip([(a @ b) / np.linalg.norm(a) / np.linalg.norm(b)
                                                      for a, b in zip(np.diff(dress, axis=0)[:-1],
                                                                      np.diff(dress, axis=0)[1:], strict=True)],
                                                     -1, 1)))]
    assert min(small) < 15 < max(small)  # arc chords (not corners) and sharp corners
    torch_path = case_path("torch")
    ends = np.linalg.norm(np.diff(torch_path, axis=0), axis=1)[[0, -1]]
    assert ends.min() >= 40 and sum(t > 120 for t in turns["torch"]) >= 5  # long handle, closely spaced spikes
    with pytest.raises(ValueError, match="unknown case"):
        case_path("star")


def test_straight_line_plan_is_a_rest_to_rest_s_curve_and_within_its_bounds():
    line = np.array([[0.0, 0.0], [50.0, 0.0]])
    _, record = assess(line, polyline_radius(line, 0.005), MACHINE, straight=True)
    ramp = ramp_distance(0.0, 100.0, 2000.0, 50000.0)
    expected = 2 * ramp_time(0.0, 100.0, 2000.0, 50000.0) + (50.0 - 2 * ramp) / 100.0
    assert record["time"] == pytest.approx(expected, rel=1e-3)
    assert record["peaks"]["feed"] == pytest.approx(100.0) and record["within_limits"] and record["bracketed"]


def test_smoothed_case_plan_keeps_every_limit():
    path = case_path("w")
    smoothed = smooth_path(path, corner_smoother("bezier"), FAST)
    _, record = assess(smoothed.points, smoothed.rho, MACHINE, straight=False)
    assert record["within_limits"] and record["bracketed"] and record["upper_bound"] is None
    assert record["peaks"]["normal_acceleration"] > 0.5 * MACHINE.normal_acceleration  # a limit that binds


def test_arc_blend_curvature_of_a_lone_corner_is_the_paths_before():
    from toolpath.corners.path import arc_blend_curvature

    (_, corner, _), = corner_frames(SQUARE, CornerSettings())
    smoothed = smooth_path(SQUARE, corner_smoother("bspline"), FAST)
    assert arc_blend_curvature(corner, 0.1) == pytest.approx(smoothed.corners[0].curvature_before, rel=1e-12)


def test_surrogates_are_not_trusted_where_there_is_no_reference_to_beat(monkeypatch):
    """Where method 1 cannot be held to delta_max the limit is infinite: the networks are not asked,
    PSO decides (a repair there once pinched a curve to a near cusp that Eq. 7 alone accepted)."""
    import math

    from toolpath.corners import network as corner_net
    from toolpath.corners.curve import Corner
    from toolpath.corners.path import surrogate_corner
    from toolpath.corners.pso import PsoSettings

    def never(*args, **kwargs):
        raise AssertionError("the networks were asked")

    monkeypatch.setattr(corner_net, "smooth_corner", never)
    corner = Corner(turn=math.radians(90), leg=1.0)
    found, source = surrogate_corner((None, None), corner, 0.1, PsoSettings(particles=8, iterations=5), math.inf)
    assert source == "pso" and found.feasible


@pytest.mark.parametrize("vertex", [10, 86])
def test_pso_is_never_sharper_than_method_1_or_the_dual_bezier_on_the_dress_corners(vertex):
    """Dress vertices 10 / 86 (turn 101.5 deg, legs 0.17 mm): method 2's flattest curve is sharper than
    method 1 at delta_max there (an earlier PSO answered 25.5 1/mm against method 1's 7.04), so the swarm
    must keep its reference; the feasible set still holds method-1-like curves (P_{i+3} on the leg)."""
    from toolpath.corners.curve import method1_at
    from toolpath.corners.path import pso_smoother
    from toolpath.corners.pso import leg_particles, swarm_fitness

    settings = CornerSettings(pso=PsoSettings(particles=16, iterations=10, seed=0))
    corner = {v: c for v, c, _ in corner_frames(case_path("dress"), settings)}[vertex]
    assert math.degrees(corner.turn) == pytest.approx(101.5, abs=0.1) and corner.leg < 0.2
    assert np.isfinite(swarm_fitness(corner, leg_particles(corner, 8), 0.1, 0.1)).any()
    found, source = pso_smoother(corner, settings)
    method1 = method1_at(corner, 0.1)
    bezier = bezier_transition(corner.turn, 2 * corner.leg, 0.1)
    assert found.feasible and found.max_curvature <= min(method1.max_curvature, bezier.max_curvature)
    assert source == ("pso: dual Bezier" if bezier.max_curvature < method1.max_curvature else "pso: method 1")


def test_pso_answer_is_method_2_where_it_is_flatter_and_every_kept_corner_says_why():
    """Dress vertex 8 (101.6 deg, L = 0.69 mm): method 2 is flatter than the dual Bezier (6.17 against 6.64)."""
    from toolpath.corners.curve import Corner

    settings = CornerSettings(pso=PsoSettings(particles=48, iterations=40, seed=0))  # the default swarm
    corner = Corner(math.radians(101.622), 0.693148)
    found, source = corner_smoother("nurbs_pso")(corner, settings, math.inf)
    bezier = bezier_transition(corner.turn, 2 * corner.leg, 0.1)
    assert source == "pso" and len(found.curve.points) == 7 and found.max_curvature < bezier.max_curvature
    reversal = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 0.1]])  # turns 179.4 deg
    (kept,) = smooth_path(reversal, corner_smoother("nurbs_pso"), settings).corners
    assert kept.source.startswith("kept: reversal")
