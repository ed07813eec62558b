"""The NURBS corner paper's NURBS (Eq. 1-6) and local corner smoothing by PSO (Eq. 7-8) on hand cases."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from toolpath.corners.curve import (
    SAMPLES,
    Corner,
    distance_to_legs,
    evaluate,
    legs,
    method1,
    method1_at,
    outside_distance,
    solve_weights,
)
from toolpath.corners.nurbs import Nurbs
from toolpath.corners.pso import PsoSettings, _candidate, pso_corner, swarm_fitness
from toolpath.corners.transitions import bezier_transition, bspline_transition
from toolpath.geometry import hausdorff


def test_rational_quadratic_quarter_circle_has_radius_one():
    """The textbook NURBS circle: (1,0), (1,1), (0,1) with weights 1, sqrt(2)/2, 1 is exact (Eq. 1, 5, 6)."""
    arc = Nurbs(np.array([[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]), np.array([1.0, math.sqrt(0.5), 1.0]), degree=2)
    u = np.linspace(0, 1, 51)
    assert np.allclose(np.linalg.norm(arc(u), axis=1), 1.0)
    assert np.allclose(arc.radius(u), 1.0)
    line = Nurbs(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]), np.ones(4))
    assert np.all(np.isinf(line.radius(u)))
    assert arc.basis(0.5).sum() == pytest.approx(1.0)


def test_square_corner_in_its_frame():
    corner = Corner(turn=math.pi / 2, leg=1.0)
    p = corner.method1_points()
    assert np.allclose(p[1], [-math.sqrt(0.5), -math.sqrt(0.5)]) and np.allclose(p[2], [0, 0])
    assert distance_to_legs(np.array([[0.0, -1.0]]), corner)[0] == pytest.approx(math.sqrt(0.5))
    # the unit-weight five-point curve cuts the corner by 0.354 mm: more than the default 0.1 mm
    assert not method1(corner, 0.1).feasible and method1(corner, 0.5).feasible


def test_weights_put_the_middle_of_the_curve_at_the_target_error():
    corner = Corner(turn=math.pi / 2, leg=1.0)
    points = corner.method2_points(np.array([-0.3, -0.2]))
    w = solve_weights(points, 0.08)
    assert w is not None and w[2] == w[4]  # the symmetric pair
    assert np.linalg.norm(Nurbs(points, w)(0.5)[0]) == pytest.approx(0.08)


@pytest.mark.parametrize("turn_degrees", [60, 90, 135])
def test_pso_returns_only_corners_that_meet_eq7_and_improves_on_its_start(turn_degrees):
    corner = Corner(turn=math.radians(turn_degrees), leg=1.0)
    best, history = pso_corner(corner, delta_max=0.1, settings=PsoSettings(particles=12, iterations=15, seed=1))
    assert best is not None and best.feasible
    assert max(best.delta_1, best.delta_2) <= 0.1 + 1e-9 and best.delta_2 == pytest.approx(0.1)
    lo, hi = corner.box()
    assert np.all(best.curve.points[2] > lo) and np.all(best.curve.points[2] < hi)
    assert np.allclose(best.curve.points[4], best.curve.points[2] * [-1, 1])  # symmetric about the y axis
    assert history[-1] <= history[0] and best.max_curvature == pytest.approx(history[-1])
    again = evaluate(corner, best.curve.points, best.curve.weights, 0.1)
    assert again.feasible and again.max_curvature == pytest.approx(best.max_curvature)


def test_pso_is_seeded_and_says_so_when_nothing_is_feasible():
    corner = Corner(turn=math.pi / 2, leg=1.0)
    settings = PsoSettings(particles=8, iterations=5, seed=7)
    a, b = pso_corner(corner, 0.1, settings=settings)[0], pso_corner(corner, 0.1, settings=settings)[0]
    assert np.array_equal(a.curve.points, b.curve.points) and np.array_equal(a.curve.weights, b.curve.weights)
    none, history = pso_corner(corner, delta_max=1e-9, settings=settings)
    assert none is None and all(math.isinf(h) for h in history)
    assert pso_corner(corner, 0.1, settings=settings, curvature_limit=0.5)[0] is None  # Eq. 7's cur_max


@pytest.mark.parametrize("seed", range(4))
def test_pso_finds_the_thin_basin_of_a_sharp_corner_from_any_seed(seed):
    """The W path's 125.4 deg corner (L = 3): the flattest curves have P_{i+3} on the leg within a few
    per cent of the corner; a swarm drawn uniformly settled on the other basin (37.9 against about
    15.9 1/mm) for most seeds.  With the method-1-like leg particles every seed comes within 1 % of a 60 x 60 grid."""
    from toolpath.corners.pso import LEG_PARTICLES, leg_particles

    corner = Corner(turn=math.radians(125.375), leg=3.0)
    lo, hi = corner.box()
    axis = [np.linspace(a, b, 62)[1:-1] for a, b in zip(lo, hi, strict=True)]
    grid = np.stack(np.meshgrid(*axis), axis=-1).reshape(-1, 2)
    grid_best = swarm_fitness(corner, grid, 0.1, 0.1).min()
    best, _ = pso_corner(corner, 0.1, settings=PsoSettings(particles=48, iterations=40, seed=seed))
    assert best.max_curvature <= 1.01 * grid_best  # within 1 % of the grid, far from the other basin (x 2.4)
    legs = leg_particles(corner, LEG_PARTICLES)
    np.testing.assert_allclose(legs[:, 0] / corner.leg_point(corner.leg, -1)[0],
                               legs[:, 1] / corner.leg_point(corner.leg, -1)[1])  # on the leg P_{i-1} -> P_i


def test_a_feasible_reference_is_the_swarms_first_best():
    corner = Corner(turn=math.pi / 2, leg=1.0)
    settings = PsoSettings(particles=8, iterations=3, seed=7)
    plain, _ = pso_corner(corner, 0.1, settings=settings)
    flatter = replace(plain, max_curvature=plain.max_curvature / 2)  # a stand-in reference flatter than PSO's
    found, history = pso_corner(corner, 0.1, settings=settings, references=[None, flatter])
    assert found is flatter and max(history) <= flatter.max_curvature
    sharper = replace(plain, max_curvature=plain.max_curvature * 2)
    assert pso_corner(corner, 0.1, settings=settings, references=[sharper])[0].max_curvature == plain.max_curvature
    infeasible = replace(plain, max_curvature=0.0, feasible=False)
    assert pso_corner(corner, 0.1, settings=settings, references=[infeasible])[0] is not infeasible


# --- FDLS / SDLS: the Double-ResNet surrogates ---------------------------------------------------------

import io  # noqa: E402

import torch  # noqa: E402

from toolpath.corners.network import (  # noqa: E402
    ResidualMLP,
    fdls_data,
    fit,
    held_inside,
    predict,
    sdls_data,
    smooth_corner,
    solved_corners,
)

FAST = PsoSettings(particles=6, iterations=6)


@pytest.fixture(scope="module")
def trained():
    samples = solved_corners(24, 0.1, seed=5, settings=FAST)
    torch.manual_seed(0)
    fdls, sdls = ResidualMLP(10, 2, width=16, layers=16, every=8), ResidualMLP(14, 7, width=16, layers=16, every=8)
    curves = (fit(fdls, *fdls_data(samples), epochs=15, batch=16, lr=0.005, seed=1),
              fit(sdls, *sdls_data(samples), epochs=15, batch=64, lr=0.001, seed=2))
    return samples, fdls, sdls, curves


def test_a_target_held_inside_keeps_a_margin_to_every_check(trained):
    samples = trained[0]
    sample = max(samples, key=lambda s: evaluate(s.corner, s.points, s.weights, 0.1).delta_2)
    assert evaluate(sample.corner, sample.points, sample.weights, 0.1).delta_2 == pytest.approx(0.1, rel=1e-6)
    assert held_inside(sample, 0.1, 0.0, 0.0) is sample  # no margin: PSO's answer as found
    held = held_inside(sample, 0.1, 0.03, 0.005)
    checked = evaluate(held.corner, held.points, held.weights, 0.1)
    assert checked.feasible and checked.delta_2 == pytest.approx(0.097, rel=1e-6)  # C(1/2) at 0.97 delta_max
    phi = sample.corner.half_opening  # the extra point moved 0.5 % of L along the incoming leg's inward normal
    moved = held.points[2] - sample.points[2]
    assert moved == pytest.approx(-0.005 * sample.corner.leg * np.array([-math.cos(phi), math.sin(phi)]))
    assert held_inside(sample, 0.1, 0.03, 0.005, limit=0.0) is sample  # no curve is flatter than 0: keep PSO's


def test_the_paper_network_is_64_layers_with_a_shortcut_every_8():
    net = ResidualMLP(10, 2)
    assert len(net.blocks) == 8 and sum(isinstance(m, torch.nn.Linear) for b in net.blocks for m in b) == 64
    with pytest.raises(ValueError, match="multiple"):
        ResidualMLP(10, 2, layers=60, every=8)


def test_solved_corners_are_feasible_and_training_lowers_the_loss(trained):
    samples, _, _, (fdls_curve, sdls_curve) = trained
    assert len(samples) == 24
    assert all(evaluate(s.corner, s.points, s.weights, 0.1).feasible for s in samples)
    assert fdls_curve[-1] < fdls_curve[0] and sdls_curve[-1] < sdls_curve[0]


def test_the_networks_reload_and_predict_deterministically(trained):
    samples, fdls, sdls, _ = trained
    buffer = io.BytesIO()
    torch.save({"fdls": fdls.state_dict(), "sdls": sdls.state_dict()}, buffer)
    buffer.seek(0)
    state = torch.load(buffer, weights_only=True)
    fdls2, sdls2 = ResidualMLP(10, 2, width=16, layers=16, every=8), ResidualMLP(14, 7, width=16, layers=16, every=8)
    fdls2.load_state_dict(state["fdls"])
    sdls2.load_state_dict(state["sdls"])
    fdls2.eval()
    sdls2.eval()
    corner = samples[0].corner
    for a, b in zip(predict(fdls, sdls, corner), predict(fdls2, sdls2, corner), strict=True):
        assert np.array_equal(a, b)


def test_smooth_corner_never_returns_an_infeasible_corner(trained):
    _, fdls, sdls, _ = trained
    for turn in (40, 90, 140):
        corner = Corner(turn=math.radians(turn), leg=1.5)
        found, source = smooth_corner(fdls, sdls, corner, 0.1, FAST)
        assert source in ("net", "repaired", "pso") and found.feasible
        assert max(found.delta_1, found.delta_2) <= 0.1 + 1e-9


class _Fixed(torch.nn.Module):
    """A stand-in network that always answers ``value``."""

    def __init__(self, value):
        super().__init__()
        self.value = torch.tensor([value], dtype=torch.float32)

    def forward(self, x):
        return self.value.expand(len(x), -1)


def test_an_answer_outside_the_corner_is_repaired_into_it():
    corner = Corner(turn=math.radians(136), leg=0.85)
    extra = np.array([-0.249, -0.205])  # where an unsigned error let PSO go: 0.154 outside the leg line
    points = corner.method2_points(extra)
    full = evaluate(corner, points, solve_weights(points, 0.1), 0.1)
    assert not full.feasible and not full.inside and full.delta_1 > 0.1
    sdls = _Fixed(np.log(solve_weights(points, 0.1)).tolist())  # the net's answer is exactly ``full``
    found, source = smooth_corner(_Fixed(extra.tolist()), sdls, corner, 0.1, FAST)
    assert source == "repaired" and found.feasible and found.inside and found.error <= 0.1 + 1e-9
    outside = smooth_corner(_Fixed([5.0, 5.0]), sdls, corner, 0.1, FAST)  # projected into the box
    assert outside[1] in ("repaired", "pso") and outside[0].feasible


@settings(max_examples=25, deadline=None, derandomize=True)
@given(turn_deg=st.floats(10.0, 170.0), leg=st.floats(0.1, 3.0), seed=st.integers(0, 1000))
def test_every_corner_curve_lies_inside_its_corner_within_delta_max(turn_deg, leg, seed):
    """PSO, method 1 at delta_max and both comparison transitions: each answer is inside the wedge of
    the two legs and within delta_max of them both ways (exact two-sided distance)."""
    corner = Corner(turn=math.radians(turn_deg), leg=leg)
    answers = [pso_corner(corner, 0.1, settings=PsoSettings(particles=8, iterations=5, seed=seed))[0],
               method1_at(corner, 0.1), bspline_transition(corner.turn, 2 * leg, 0.1),
               bezier_transition(corner.turn, 2 * leg, 0.1)]
    for found in answers:
        if found is None or not found.feasible:
            continue
        samples = found.curve(np.linspace(0.0, 1.0, SAMPLES))
        own = Corner(corner.turn, float(np.linalg.norm(samples[0])) / 2.0)  # its legs end where it starts
        assert outside_distance(samples, own).max() <= 1e-9
        assert float(hausdorff(samples, legs(own))) <= 0.1 + 1e-9
        assert found.error >= float(hausdorff(samples, legs(own))) - 1e-12  # the check is an upper bound


def test_method1_at_delta_max_puts_the_middle_at_delta_max():
    corner = Corner(turn=math.radians(90), leg=1.0)
    found = method1_at(corner, 0.1)
    assert found.feasible and found.inside
    assert found.delta_2 == pytest.approx(0.1)
    # unit weights on the same legs sit farther from the corner (0.25 mm here): held to 0.1 it is sharper
    assert method1(corner, math.inf).delta_2 > 0.1 and found.max_curvature > method1(corner, math.inf).max_curvature


def test_the_wedge_of_a_right_angle_corner():
    corner = Corner(turn=math.radians(90), leg=1.0)
    inside, outside = np.array([[0.0, -0.5]]), np.array([[0.0, 0.5]])
    assert outside_distance(inside, corner)[0] == pytest.approx(-0.5 * math.sqrt(0.5))
    assert outside_distance(outside, corner)[0] == pytest.approx(0.5 * math.sqrt(0.5))


@pytest.mark.parametrize("turn_deg, leg", [(30.0, 0.5), (90.0, 1.0), (150.0, 3.0)])
def test_the_swarm_is_scored_as_each_candidate_alone(turn_deg, leg):
    """swarm_fitness (all particles at once) gives each particle's evaluate() curvature, inf where infeasible."""
    corner = Corner(turn=math.radians(turn_deg), leg=leg)
    lo, hi = corner.box()
    extras = np.random.default_rng(7).uniform(lo, hi, (64, 2))
    batch = swarm_fitness(corner, extras, 0.1, 0.1)
    for extra, got in zip(extras, batch, strict=True):
        one = _candidate(corner, extra, 0.1, 0.1)
        expected = one.max_curvature if one is not None and one.feasible else math.inf
        assert got == pytest.approx(expected, rel=1e-9) if math.isfinite(expected) else math.isinf(got)
    assert np.isfinite(batch).any() and np.isinf(batch).any()  # both outcomes are exercised


def test_a_margin_outside_zero_to_one_is_refused_before_any_corner_is_solved():
    from toolpath.corners.runs import train_surrogates

    def never(*_):
        raise AssertionError("the PSO dataset was solved before the margin was checked")

    ccfg = {"dataset": {"train": 4, "test": 2, "turns_deg": [30, 150], "legs": [0.5, 3.0],
                        "margin": {"delta": -0.1, "wedge": 0.0}}}
    with pytest.raises(ValueError, match=r"corner.dataset.margin .*fractions in \[0, 1\)"):
        train_surrogates(ccfg, None, 0, never)


def test_surrogate_fits_in_worker_processes_equal_the_fits_in_this_one():
    """FDLS / SDLS are fitted side by side in spawned workers (each seeds itself and runs the stage's
    thread count): the weights and loss curves are the bits an in-process fit gives."""
    from types import SimpleNamespace

    import torch

    from toolpath.corners.runs import _fit
    from toolpath.pipeline.workers import pool_map

    rng = np.random.default_rng(4)
    samples = [SimpleNamespace(method1=rng.normal(size=(7, 2)), points=rng.normal(size=(7, 2)),
                               weights=rng.uniform(0.5, 2.0, 7)) for _ in range(24)]
    ccfg = {"threads": 1, "net": {"width": 8, "layers": 4, "every": 2, "dropout": 0.1},
            "fdls": {"epochs": 3, "batch": 4, "lr": 0.005}, "sdls": {"epochs": 3, "batch": 8, "lr": 0.001}}
    sets = [samples, samples[:12]]
    threads = torch.get_num_threads()
    try:
        here = _fit(ccfg, sets, 7, lambda fn, jobs, label: [fn(job) for job in jobs])
    finally:
        torch.set_num_threads(threads)  # the in-process fit sets this process's count
    apart = _fit(ccfg, sets, 7, lambda fn, jobs, label: pool_map(fn, jobs, 2, label))
    for (nets, curves), (nets2, curves2) in zip(here, apart, strict=True):
        assert curves == curves2
        for name in ("fdls", "sdls"):
            one, two = nets[name].state_dict(), nets2[name].state_dict()
            assert all(torch.equal(one[k], two[k]) for k in one) and not nets2[name].training
    assert here[0][1]["fdls"] != here[1][1]["fdls"]  # each set is fitted on its own samples
