"""The exact two-sided distance: hand cases where the answer lies inside a segment, and agreement with
shapely's densified Hausdorff distance and with dense sampling on random polylines."""

import importlib

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from toolpath.geometry import directed_hausdorff, hausdorff, point_to_polyline
from toolpath.geometry.hausdorff import WHOLE_PAIRS, _far_out_of_band, moved_hausdorff, pieced_hausdorff

# the module itself (the package exports a function of the same name)
hausdorff_module = importlib.import_module("toolpath.geometry.hausdorff")


@pytest.fixture(params=["compiled", "numpy"])
def pieced_path(request, monkeypatch):
    """pieced_hausdorff's compiled loops (numba, the ``fast`` extra) and its NumPy functions, in turn; how near
    each must come to the whole measure: the NumPy path to the last bit, the loops (the same candidates, no
    subdivision of long segments) within rounding."""
    if request.param == "compiled":
        if hausdorff_module.compiled_kernels() is None:
            pytest.skip("numba is not installed (the fast extra): the compiled loops are not there to test")
        return {"rel": 1e-12, "abs": 0.0}
    monkeypatch.setattr(hausdorff_module, "compiled_kernels", lambda: None)
    return {"rel": 0.0, "abs": 0.0}


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


def _moved(kind: int, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    if kind == 0:  # a wavy cut, the usual case: every far segment is far in space
        t = np.arange(n) * 0.2
        a = np.c_[t, np.sin(t)]
    elif kind == 1:  # a hairpin whose legs lie 0.015 apart: far in index, near in space
        t = np.arange(n) * 0.1
        a = np.c_[np.where(t < t[n // 2], t, 2 * t[n // 2] - t), np.where(t < t[n // 2], 0.0, 0.015)]
    else:  # steps much shorter than the moves
        a = np.cumsum(rng.normal(0, 0.01, (n, 2)), axis=0)
    b = a + rng.normal(0, 0.004, a.shape)
    b[0], b[-1] = a[0], a[-1]
    return a, b


def test_moved_polylines_measured_in_a_band_equal_the_whole_measure():
    rng = np.random.default_rng(3)
    pairs = [_moved(k % 3, int(rng.integers(3, 60)), rng) for k in range(90)]
    old, new = [a for a, _ in pairs], [b for _, b in pairs]
    whole = np.array([float(hausdorff(a, b)) for a, b in pairs])
    assert moved_hausdorff(old, new) == pytest.approx(whole, rel=1e-12, abs=1e-15)
    assert moved_hausdorff(old, new, band=1) == pytest.approx(whole, rel=1e-12, abs=1e-15)


def test_moved_hand_cases():
    line = np.c_[np.arange(10.0), np.zeros(10)]
    lifted = line + [0.0, 0.3]
    bump = line.copy()
    bump[5, 1] = 0.5  # one vertex lifted: its distance to the old line is the whole 0.5
    assert moved_hausdorff([line, line, line], [lifted, bump, line]).tolist() == pytest.approx([0.3, 0.5, 0.0])
    # a hairpin's legs 0.01 apart, a point of the first leg moved 0.02 up, past the second leg: it is
    # 0.01 from the old path (the other leg), not 0.02 (its own leg, all a band sees); the band test
    # must notice the near leg and measure the pair whole
    legs = np.r_[np.c_[np.arange(8.0), np.zeros(8)], np.c_[np.arange(7.0, -1.0, -1.0), np.full(8, 0.01)]]
    moved = legs.copy()
    moved[3, 1] = 0.02
    assert not _far_out_of_band(legs[None], moved[None], 2)[0] and _far_out_of_band(line[None], bump[None], 2)[0]
    assert moved_hausdorff([legs], [moved])[0] == pytest.approx(0.01, rel=1e-9)
    with pytest.raises(ValueError, match="keep its number of points"):
        moved_hausdorff([line, line], [line, line[:-1]])


def test_pieced_measure_of_long_polylines_equals_the_whole_measure(pieced_path):
    """A circle as 1,000 fine chords against 100 coarse ones (sag R(1 - cos(pi/100)) = 0.0049 mm at R 10),
    and a wandering line against a copy with one spike, hairpin legs included: measured in pieces against
    the stretch that can hold the nearest points, the figure is the whole measure's to the last bit."""
    fine_t, coarse_t = np.linspace(0.0, 2 * np.pi, 1001), np.linspace(0.0, 2 * np.pi, 101)
    fine = 10.0 * np.c_[np.cos(fine_t), np.sin(fine_t)]
    coarse = 10.0 * np.c_[np.cos(coarse_t), np.sin(coarse_t)]
    assert len(fine) * len(coarse) > WHOLE_PAIRS
    pieced = pieced_hausdorff(fine, coarse)
    assert pieced == pytest.approx(10.0 * (1 - np.cos(np.pi / 100)), rel=1e-6)
    assert pieced == pytest.approx(float(hausdorff(fine, coarse)), **pieced_path)
    rng = np.random.default_rng(5)
    walk = np.cumsum(rng.normal(0.0, 1.0, (800, 2)), axis=0)
    spiked = walk.copy()
    spiked[400] += [0.0, 3.0]
    assert pieced_hausdorff(walk, spiked, piece=16) == pytest.approx(float(hausdorff(walk, spiked)), **pieced_path)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_pieced_measure_of_paths_passing_near_themselves_equals_the_whole_measure(seed, pieced_path):
    """Each piece finds its stretch of the other path from distances bounded by the stretch near it, not
    by the whole path: two and a half noisy turns against a coarser copy, one of them reversed (the
    nearest segment may lie on another turn), measure exactly as the whole does."""
    rng = np.random.default_rng(seed)
    t, s = np.linspace(0.0, 5 * np.pi, 900), np.linspace(0.0, 5 * np.pi, 300)
    a = np.c_[np.cos(t), np.sin(t)] * (10.0 + 0.02 * t[:, None]) + rng.normal(0.0, 0.05, (900, 2))
    b = np.c_[np.cos(s), np.sin(s)] * (10.0 + 0.02 * s[:, None]) + rng.normal(0.0, 0.3, (300, 2))
    whole = float(hausdorff(a, b))
    assert pieced_hausdorff(a, b, piece=16) == pytest.approx(whole, **pieced_path)
    assert pieced_hausdorff(a, b[::-1], piece=16) == pytest.approx(whole, **pieced_path)


def test_compiled_pieced_loops_on_hand_cases():
    """The compiled loops alone: a chord cutting a square corner is 2.5 from the corner path (its middle to
    either leg) and the corner's vertex 5 / sqrt(2) from the chord; a line shifted by 0.3 is 0.3 off both ways
    whatever the pieces; a line over a sawtooth is 1 / sqrt(2) from it, and the sawtooth 1 from the line."""
    kernels = hausdorff_module.compiled_kernels()
    if kernels is None:
        pytest.skip("numba is not installed (the fast extra): the compiled loops are not there to test")
    corner = np.array([[0.0, 0.0], [5.0, 0.0], [5.0, 5.0]])
    chord = np.array([[0.0, 0.0], [5.0, 5.0]])
    assert kernels.directed_pieced(chord, corner, 32) == pytest.approx(2.5)
    assert kernels.directed_pieced(corner, chord, 32) == pytest.approx(5.0 / np.sqrt(2.0))
    line = np.c_[np.linspace(0.0, 10.0, 97), np.zeros(97)]
    shifted = np.c_[np.linspace(0.0, 10.0, 41), np.full(41, 0.3)]
    for piece in (1, 3, 32):
        assert kernels.directed_pieced(line, shifted, piece) == pytest.approx(0.3)
        assert kernels.directed_pieced(shifted, line, piece) == pytest.approx(0.3)
    # a coarse line over a fine sawtooth (peaks on it at even x, valleys 1 below at odd x): each coarse segment
    # runs past four teeth, bounded by their crossings alone; between two peaks the line's farthest point
    # is 1 / sqrt(2) from either flank, and the valleys are 1 from the line
    saw = np.c_[np.arange(9.0), -(np.arange(9) % 2.0)]
    coarse = np.array([[0.0, 0.0], [4.0, 0.0], [8.0, 0.0]])
    for piece in (1, 2, 32):
        assert kernels.directed_pieced(coarse, saw, piece) == pytest.approx(1.0 / np.sqrt(2.0))
        assert kernels.directed_pieced(saw, coarse, piece) == pytest.approx(1.0)
    # asked for (a caller with many short pairs), the loops measure short pairs too: the whole measure's figure
    rng = np.random.default_rng(2)
    walk = np.cumsum(rng.normal(0.0, 1.0, (60, 2)), axis=0)
    other = walk[::3] + rng.normal(0.0, 0.4, (20, 2))
    assert pieced_hausdorff(walk, other, compiled=True) == pytest.approx(float(hausdorff(walk, other)), rel=1e-12)
    assert pieced_hausdorff(corner, chord, compiled=True) == pytest.approx(5.0 / np.sqrt(2.0))
