"""The exact two-sided distance: hand cases where the answer lies inside a segment, and agreement with
shapely's densified Hausdorff distance and with dense sampling on random polylines."""

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from toolpath.geometry import directed_hausdorff, hausdorff, point_to_polyline


def dense(polyline: np.ndarray, per_segment: int = 400) -> np.ndarray:
    t = np.linspace(0.0, 1.0, per_segment, endpoint=False)
    a, b = polyline[:-1], polyline[1:]
    return np.vstack([(a[:, None] + t[None, :, None] * (b - a)[:, None]).reshape(-1, 2), polyline[-1:]])


def test_a_shifted_line_is_its_shift_away_both_ways():
    line = np.array([[0.0, 0.0], [4.0, 0.0], [10.0, 0.0]])
    assert hausdorff(line, line + [0.0, 0.3]) == pytest.approx(0.3)


def test_a_cut_corner_is_measured_from_the_corner_not_from_the_vertices():
    corner = np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]])
    chord = np.array([[0.0, 0.0], [5.0, 5.0]])
    # every vertex of the chord lies on the corner path: a vertex-only measure says 0 one way
    assert directed_hausdorff(chord, corner) == pytest.approx(2.5)  # the chord's middle to either leg
    assert hausdorff(corner, chord) == pytest.approx(5 / np.sqrt(2))


def test_the_farthest_point_can_lie_inside_a_segment():
    # the bottom of a U: both its vertices lie on the U, its middle is 5 from all three sides
    bottom = np.array([[0.0, 0.0], [10.0, 0.0]])
    u = np.array([[0.0, 0.0], [0.0, 5.0], [10.0, 5.0], [10.0, 0.0]])
    assert point_to_polyline(bottom, u).max() == 0.0
    assert directed_hausdorff(bottom, u) == pytest.approx(5.0)


def test_a_spike_flattened_away_is_its_height_from_the_new_path():
    spike = np.array([[0.0, 0.0], [5.0, 0.0], [5.1, 2.0], [5.2, 0.0], [10.0, 0.0]])
    flat = np.array([[0.0, 0.0], [10.0, 0.0]])
    # the flat line's point under the spike, (5.1, 0), is 0.2 / sqrt(4.01) from the spike's flanks
    assert directed_hausdorff(flat, spike) == pytest.approx(0.2 / np.sqrt(4.01))
    assert hausdorff(flat, spike) == pytest.approx(2.0)


def test_batched_and_broadcast():
    a = np.zeros((4, 5, 2))
    a[..., 0] = np.arange(5)
    b = a.copy()
    b[:, 2, 1] = np.arange(4)
    assert hausdorff(a, b).tolist() == pytest.approx([0, 1, 2, 3])
    assert hausdorff(a[0], b).shape == (4,)


def test_agrees_with_shapely_and_dense_sampling_on_random_polylines():
    rng = np.random.default_rng(7)
    for _ in range(60):
        n, m = rng.integers(2, 9, 2)
        a, b = rng.normal(size=(n, 2)), rng.normal(size=(m, 2))
        ours = float(hausdorff(a, b))
        sampled = max(point_to_polyline(dense(a), b).max(), point_to_polyline(dense(b), a).max())
        theirs = shapely.hausdorff_distance(shapely.LineString(a), shapely.LineString(b), densify=0.002)
        # sampling can only miss the maximum, never exceed it; finer sampling closes in on it
        assert sampled <= ours + 1e-9 and theirs <= ours + 1e-9
        assert ours - sampled < 5e-3 and ours - theirs < 5e-3


coordinates = arrays(np.float64, st.tuples(st.integers(2, 7), st.just(2)),
                     elements=st.floats(-10, 10, allow_nan=False, width=32))


@settings(max_examples=150, deadline=None)
@given(coordinates, coordinates)
def test_never_below_dense_sampling_and_symmetric(a, b):
    ours = float(hausdorff(a, b))
    assert ours == pytest.approx(float(hausdorff(b, a)), abs=1e-9)
    sampled = max(point_to_polyline(dense(a, 200), b).max(), point_to_polyline(dense(b, 200), a).max())
    assert sampled <= ours + 1e-9
