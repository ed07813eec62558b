"""The shared smoothing problem and the mean-filter / Bezier smoothers on hand-made windows."""

import numpy as np
import pytest

from toolpath.geometry import hausdorff, local_curvature
from toolpath.smoothing import SmoothingProblem, bezier_fit, clip_displacement, mean_filter


def zigzag(n=50, amplitude=0.05):
    x = np.linspace(0, 10, n)
    y = amplitude * (np.arange(n) % 2)
    y[0] = y[-1] = 0.0
    return np.column_stack([x, y])


def test_mean_filter_keeps_a_straight_line_and_the_ends():
    line = np.column_stack([np.linspace(0, 5, 20), np.linspace(1, 3, 20)])
    assert np.allclose(mean_filter(line, 5, passes=3), line)
    zz = zigzag()
    out = mean_filter(zz, 3, passes=2)
    assert np.array_equal(out[[0, -1]], zz[[0, -1]])
    assert local_curvature(out) < 0.2 * local_curvature(zz)
    with pytest.raises(ValueError, match="odd"):
        mean_filter(zz, 4)


def test_mean_filter_of_width_3_by_hand():
    pts = np.array([[0, 0], [1, 3], [2, 0], [3, 0]], dtype=float)
    assert mean_filter(pts, 3)[1:3].tolist() == [[1, 1], [2, 1]]  # (0+3+0)/3 and (3+0+0)/3


def test_a_width_of_one_leaves_the_window_and_many_windows_filter_as_each_alone():
    zz = zigzag(9)
    assert mean_filter(zz, 1, passes=2) == pytest.approx(zz, abs=1e-15)  # once an empty slice and a crash
    rng = np.random.default_rng(2)
    many = zigzag()[None] + rng.normal(0, 0.02, (6, 50, 2))
    for width, passes in ((3, 1), (5, 3), (7, 2)):
        together = mean_filter(many, width, passes)
        assert all(np.array_equal(together[k], mean_filter(many[k], width, passes)) for k in range(len(many)))


@pytest.mark.parametrize("method", ["mean_filter", "nacoa", "bezier"])
def test_windows_smoothed_together_get_what_each_gets_alone(method):
    from toolpath.smooth.command import SMOOTHING
    from toolpath.smoothing.methods import smooth, smooth_together

    rng = np.random.default_rng(8)
    windows = [zigzag(20) + rng.normal(0, 0.02, (20, 2)) for _ in range(4)]
    cfg = {**SMOOTHING, "tolerance": 0.01, "nacoa": {**SMOOTHING["nacoa"], "generations": 6}}
    together = smooth_together(windows, method, cfg, "bound", [3, 4, 5, 6])
    for window, seed, result in zip(windows, [3, 4, 5, 6], together, strict=True):
        alone = smooth(window, method, cfg, "bound", seed, check=False)
        assert np.array_equal(alone.points, result.points) and alone.objective == result.objective


def test_bezier_fit_keeps_a_line_and_follows_a_circular_arc():
    line = np.column_stack([np.linspace(0, 5, 30), np.linspace(0, 2, 30)])
    assert np.allclose(bezier_fit(line, degree=5), line)
    angle = np.linspace(0, np.pi / 2, 50)
    arc = 10 * np.column_stack([np.cos(angle), np.sin(angle)])
    fitted = bezier_fit(arc, degree=5)
    assert np.array_equal(fitted[[0, -1]], arc[[0, -1]])
    assert np.abs(np.hypot(*fitted.T) - 10).max() < 1e-3  # a quintic follows a quarter circle closely


def test_bezier_fit_smooths_a_zigzag_and_keeps_the_point_count():
    zz = zigzag()
    out = bezier_fit(zz, degree=5)
    assert out.shape == zz.shape and local_curvature(out) < 0.05 * local_curvature(zz)


def test_clip_displacement_projects_onto_the_disc():
    moved = np.array([[0.0, 1.0], [0.01, 0.0], [-3.0, 4.0]])
    out = clip_displacement(moved, 0.05)
    assert np.allclose(out, [[0.0, 0.05], [0.01, 0.0], [-0.03, 0.04]])  # (-3, 4) / 5 * 0.05
    assert np.hypot(*out.T).max() <= 0.05


@pytest.mark.parametrize("mode", ["none", "penalty", "bound"])
def test_problem_objective_is_eq10_plus_fidelity(mode):
    bump = np.array([[0, 0], [1, 0.2], [2, 0]], dtype=float)
    problem = SmoothingProblem(bump, mode=mode, tolerance=0.05, weight=10.0)
    assert problem.dimension == 2
    flat = problem.displacement(np.array([[0, 0], [1, 0], [2, 0]], dtype=float))
    pts = problem.points(flat)
    if mode == "bound":  # (1, 0) is 0.2 below the bump's tip: the tip moves down by 0.05 only
        assert pts[1].tolist() == pytest.approx([1.0, 0.15])
        assert hausdorff(pts, bump) == pytest.approx(0.05)
        return
    assert np.allclose(pts[:, 1], 0.0)
    expected = 10 * 0.2 if mode == "penalty" else 0.0  # a straight line: Fitness 0; the tip moved 0.2
    assert problem.objective(flat) == pytest.approx(expected)
    assert problem.objective(np.zeros((3, 2)))[0] == pytest.approx(problem.objective(np.zeros(2)))


def test_bound_mode_never_returns_a_window_beyond_the_tolerance_both_ways():
    rng = np.random.default_rng(0)
    problem = SmoothingProblem(zigzag(), mode="bound", tolerance=0.05)
    pts = problem.points(rng.normal(scale=1.0, size=(200, problem.dimension)))
    assert hausdorff(pts, problem.window).max() <= 0.05 + 1e-12
    assert np.array_equal(pts[:, [0, -1]], np.broadcast_to(problem.window[[0, -1]], (200, 2, 2)))


def test_problem_rejects_unknown_mode():
    with pytest.raises(ValueError, match="fidelity mode"):
        SmoothingProblem(zigzag(), mode="loose")
    with pytest.raises(ValueError, match="positive"):
        SmoothingProblem(zigzag(), tolerance=0.0)


def test_mean_filter_gives_scipys_numbers_bit_for_bit():
    """The mean filter runs its sums as scipy.ndimage's uniform_filter1d does (toolpath smooth needs no
    SciPy): on random windows, widths, passes and batches, the same bytes as the scipy formulation."""
    from scipy.ndimage import uniform_filter1d

    def with_scipy(window, width, passes):
        half, pts = width // 2, np.asarray(window, dtype=np.float64).copy()
        for _ in range(passes):
            first, last = pts[..., :1, :], pts[..., -1:, :]
            padded = np.concatenate([2 * first - pts[..., half:0:-1, :], pts,
                                     2 * last - pts[..., -2:-half - 2:-1, :]], axis=-2)
            smoothed = uniform_filter1d(padded, size=width, axis=-2, mode="nearest")
            pts[..., 1:-1, :] = smoothed[..., half:padded.shape[-2] - half, :][..., 1:-1, :]
        return pts

    rng = np.random.default_rng(7)
    for trial in range(300):
        n, width, passes = int(rng.integers(8, 60)), int(rng.choice([1, 3, 5, 7, 9])), int(rng.integers(1, 4))
        shape = (n, 2) if trial % 2 else (3, n, 2)
        window = rng.normal(size=shape).cumsum(axis=-2) * rng.choice([1e-3, 1.0, 1e3]) + rng.choice([0.0, 1e4])
        assert mean_filter(window, width, passes).tobytes() == with_scipy(window, width, passes).tobytes()
