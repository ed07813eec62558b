"""The tube bound (toolpath.smoothing.tube) on hand-built cases: a square corner, a straight line."""

import numpy as np

from toolpath.geometry import hausdorff
from toolpath.smoothing.tube import feasible, repair, tube_certified, within_discs


def square_corner(n_leg: int = 11, spacing: float = 0.1) -> np.ndarray:
    """(0, 1) down to (0, 0), then out to (1, 0): one 90 degree corner at the origin, points 0.1 mm apart."""
    down = np.column_stack([np.zeros(n_leg), np.linspace(1.0, 0.0, n_leg)])
    out = np.column_stack([np.linspace(0.0, 1.0, n_leg), np.zeros(n_leg)])[1:]
    return np.vstack([down, out])


def with_corner(window: np.ndarray, neighbours: float, vertex: float) -> np.ndarray:
    """The corner's two neighbours moved to ``neighbours`` mm from it along the legs, the vertex to
    ``(vertex, vertex)``."""
    out = window.copy()
    corner = int(np.flatnonzero((window == 0).all(axis=1))[0])
    out[corner - 1], out[corner + 1], out[corner] = [0.0, neighbours], [neighbours, 0.0], [vertex, vertex]
    return out


def test_sliding_points_round_a_corner_the_discs_forbid():
    window, tolerance = square_corner(), 0.05
    # neighbours slide 0.06 mm towards the corner (outside their discs); by hand, the farthest points are
    # the old vertex and the new one: |(0.02, 0.02)| = 0.02 sqrt 2 both ways
    candidate = with_corner(window, 0.04, 0.02)
    assert not within_discs(candidate, window, tolerance)
    assert abs(float(hausdorff(candidate, window)) - 0.02 * np.sqrt(2)) < 1e-12
    assert tube_certified(candidate, window, tolerance) and feasible(candidate, window, tolerance)


def test_a_cut_deeper_than_the_tolerance_is_refused():
    window, tolerance = square_corner(), 0.05
    candidate = with_corner(window, 0.1, 0.045)  # the old vertex is 0.045 sqrt 2 = 0.0636 mm from the new path
    assert abs(float(hausdorff(candidate, window)) - 0.045 * np.sqrt(2)) < 1e-12
    assert not feasible(candidate, window, tolerance)


def test_points_running_backwards_are_refused_even_near_the_path():
    window = np.column_stack([np.linspace(0, 4.9, 50), np.zeros(50)])  # a straight line
    swapped = window.copy()
    swapped[[10, 11]] = swapped[[11, 10]]  # each point on the line, order broken: the path doubles back
    assert not tube_certified(swapped, window, 0.05)
    assert within_discs(swapped, window, 0.1001) and not within_discs(swapped, window, 0.05)  # each moved 0.1
    assert float(hausdorff(swapped, window)) < 1e-12  # the same point set: Frechet, not Hausdorff, fails


def test_repair_pulls_a_point_onto_the_tube_rim_and_keeps_the_ends():
    window = np.column_stack([np.linspace(0, 4.9, 50), np.zeros(50)])
    moved = window.copy()
    moved[20, 1] = 0.3  # 0.3 mm off a straight line
    fixed = repair(moved, window, 0.05)
    assert abs(fixed[20, 1] - 0.05) < 1e-9 and fixed[20, 0] == window[20, 0]
    assert np.array_equal(fixed[[0, -1]], window[[0, -1]])
    assert feasible(fixed, window, 0.05) and float(hausdorff(fixed, window)) <= 0.05 + 1e-12


def test_random_certified_candidates_are_within_the_tolerance_exactly():
    rng = np.random.default_rng(7)
    window = square_corner() + rng.normal(0, 0.01, (21, 2))
    window[[0, -1]] = square_corner()[[0, -1]]
    tolerance = 0.05
    slide = np.cumsum(rng.normal(0, 0.03, (400, 21, 2)), axis=1) * 0.3
    candidates = repair(window + slide, window, tolerance)
    candidates[:, [0, -1]] = window[[0, -1]]
    ok = feasible(candidates, window, tolerance)
    assert ok.sum() > 10
    assert (np.asarray(hausdorff(candidates[ok], window)) <= tolerance + 1e-12).all()


def _matching_by_hand(candidate: np.ndarray, window: np.ndarray, tolerance: float) -> bool:
    """Conditions 1-3 of toolpath.smoothing.tube, point by point in plain Python (the compiled loops'
    reference): the nearest foot on the BAND segments each side, feet in order, vertices between."""
    n, band = len(window), 2
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(window, axis=0), axis=1))])
    feet = [0.0]
    for i in range(1, n - 1):
        best = None
        for k in sorted({min(max(i + c, 0), n - 2) for c in range(-band, band)}):
            a, u = window[k], window[k + 1] - window[k]
            t = min(max(float(np.dot(candidate[i] - a, u) / np.dot(u, u)), 0.0), 1.0)
            d = float(np.linalg.norm(candidate[i] - (a + t * u)))
            if best is None or d < best[0]:
                best = (d, arc[k] + t * np.linalg.norm(u))
        if best[0] > tolerance:
            return False
        feet.append(best[1])
    feet.append(arc[-1])
    if any(b < a for a, b in zip(feet[:-1], feet[1:], strict=True)):
        return False
    for i in range(n - 1):
        a, u = candidate[i], candidate[i + 1] - candidate[i]
        running = -np.inf
        for j in sorted({min(max(i + c, 1), n - 2) for c in range(-band + 1, band + 1)}):
            if not feet[i] < arc[j] < feet[i + 1]:
                continue
            t = min(max(float(np.dot(window[j] - a, u) / max(np.dot(u, u), 1e-300)), 0.0), 1.0)
            if np.linalg.norm(window[j] - (a + t * u)) > tolerance or t < running:
                return False
            running = max(running, t)
    return True


def test_the_compiled_certificate_agrees_with_the_matching_written_out_by_hand():
    rng = np.random.default_rng(11)
    window = square_corner() + rng.normal(0, 0.01, (21, 2))
    window[[0, -1]] = square_corner()[[0, -1]]
    tolerance = 0.05
    candidates = window + rng.normal(0, 1.0, (300, 1, 1)) * rng.normal(0, 0.03, (300, 21, 2))
    candidates[:, [0, -1]] = window[[0, -1]]
    compiled = tube_certified(candidates, window, tolerance)
    by_hand = np.array([_matching_by_hand(c, window, tolerance) for c in candidates])
    assert 10 < by_hand.sum() < 290  # both outcomes are exercised
    assert (compiled == by_hand).all()
