"""Mean filtering and least-squares Bezier fitting of a window (the paper's category 2 and 3 methods)."""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.special import comb


def mean_filter(window: np.ndarray, width: int = 3, passes: int = 1) -> np.ndarray:
    """Moving average of ``width`` points (odd), repeated ``passes`` times; end points stay fixed.

    Near the ends the window is extended by point reflection through its end points
    (``2 p_0 - p_k``), so a straight line with evenly spaced points is left exactly where it is.
    ``window`` is (n, 2), or (..., n, 2) for many windows of one length at once (each filtered as alone).
    """
    if width < 1 or width % 2 == 0:
        raise ValueError(f"mean filter width must be odd and positive, got {width}")
    half = width // 2
    pts = np.asarray(window, dtype=np.float64).copy()
    if half >= pts.shape[-2]:
        raise ValueError(f"mean filter width {width} is too wide for a window of {pts.shape[-2]} points")
    for _ in range(passes):
        first, last = pts[..., :1, :], pts[..., -1:, :]
        padded = np.concatenate([2 * first - pts[..., half:0:-1, :], pts,
                                 2 * last - pts[..., -2:-half - 2:-1, :]], axis=-2)
        smoothed = uniform_filter1d(padded, size=width, axis=-2, mode="nearest")[..., half:padded.shape[-2] - half, :]
        pts[..., 1:-1, :] = smoothed[..., 1:-1, :]
    return pts


def _chord_parameters(points: np.ndarray) -> np.ndarray:
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    total = step.sum()
    if total == 0:
        return np.linspace(0.0, 1.0, len(points))
    return np.concatenate([[0.0], np.cumsum(step)]) / total


def bernstein(degree: int, t: np.ndarray) -> np.ndarray:
    """Bernstein basis, shape (len(t), degree + 1)."""
    k = np.arange(degree + 1)
    return comb(degree, k) * t[:, None] ** k * (1.0 - t[:, None]) ** (degree - k)


def bezier_fit(window: np.ndarray, degree: int = 5) -> np.ndarray:
    """Least-squares Bezier curve of ``degree`` through the window's fixed end points.

    The control points are fitted at chord-length parameters (numpy least squares with the first and
    last control points pinned to the window's ends) and the curve is evaluated at those same
    parameters, so the result has the window's point count and ends.
    """
    pts = np.asarray(window, dtype=np.float64)
    degree = min(degree, len(pts) - 1)
    t = _chord_parameters(pts)
    basis = bernstein(degree, t)
    rhs = pts - np.outer(basis[:, 0], pts[0]) - np.outer(basis[:, -1], pts[-1])
    inner, *_ = np.linalg.lstsq(basis[:, 1:-1], rhs, rcond=None)
    control = np.vstack([pts[0], inner, pts[-1]])
    out = basis @ control
    out[0], out[-1] = pts[0], pts[-1]
    return out
