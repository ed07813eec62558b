"""Property: in ``bound`` mode every smoothing method returns a window within the tolerance of the
original, both ways (the exact two-sided distance), with its end points kept."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from toolpath.geometry import hausdorff
from toolpath.smoothing.methods import METHODS, smooth

CFG = {"tolerance": 0.05, "penalty_weight": 10.0, "box": 0.25,
       "mean_filter": {"width": 5, "passes": 3}, "bezier": {"degree": 5},
       # Table 6's matched budget: 6 x 2 + 6 x 1 x (1 + 2 x 96) = 1,170 charged evaluations for mealpy
       "head_to_head": {"population": 6, "generations": 1, "hba_generations": 1, "m0": 2, "m_max": 2},
       "nacoa": {"population": 8, "generations": 6, "hba_generations": 1, "m0": 4, "m_min": 2, "m_max": 4,
                 "exchange_every": 3}}


@st.composite
def rough_windows(draw):
    """A 50-point window along a line or an arc, with noise, a few spikes, and uneven spacing."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = 50
    t = np.sort(rng.uniform(0, 1, n))
    t[0], t[-1] = 0.0, 1.0
    bend = draw(st.floats(0.0, 3.0))
    radius = draw(st.floats(2.0, 50.0))
    angle = bend * t
    base = radius * np.column_stack([np.sin(angle), 1 - np.cos(angle)]) if bend > 0 else \
        np.column_stack([radius * t, np.zeros(n)])
    noise = rng.normal(scale=draw(st.floats(0.0, 0.3)), size=(n, 2))
    spikes = rng.choice(n, size=draw(st.integers(0, 4)), replace=False)
    noise[spikes] *= 10
    return base + noise


@pytest.mark.parametrize("method", METHODS)
@settings(max_examples=8, deadline=None, derandomize=True)
@given(window=rough_windows(), tolerance=st.floats(0.001, 0.3), seed=st.integers(0, 1000))
def test_every_method_keeps_the_two_sided_tolerance(method, window, tolerance, seed):
    if method not in ("mean_filter", "bezier", "nacoa", "nacoa_permute"):
        pytest.importorskip("mealpy", reason="mealpy is installed by `make install` with --no-deps")
    result = smooth(window, method, {**CFG, "tolerance": tolerance}, "bound", seed=seed)
    assert float(hausdorff(result.points, window)) <= tolerance + 1e-9
    assert np.array_equal(result.points[[0, -1]], window[[0, -1]])


@pytest.mark.parametrize("method", ["mean_filter", "bezier", "nacoa", "nacoa_matched", "pso"])
@settings(max_examples=8, deadline=None, derandomize=True)
@given(window=rough_windows(), tolerance=st.floats(0.001, 0.3), seed=st.integers(0, 1000))
def test_tube_mode_keeps_the_two_sided_tolerance_measured_exactly(method, window, tolerance, seed):
    """The tube's matching certificate is only sufficient: the exact distance is the judge (``check=False``
    so that a certificate that lied would show here, not as the safety net's AssertionError)."""
    if method == "pso":
        pytest.importorskip("mealpy", reason="mealpy is installed by `make install` with --no-deps")
    result = smooth(window, method, {**CFG, "tolerance": tolerance}, "tube", seed=seed, check=False)
    assert float(hausdorff(result.points, window)) <= tolerance + 1e-9
    assert np.array_equal(result.points[[0, -1]], window[[0, -1]])
