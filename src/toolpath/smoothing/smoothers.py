"""Mean filtering and least-squares Bezier fitting of a window (the paper's category 2 and 3 methods)."""

from __future__ import annotations

import math

import numpy as np


def running_mean(values: np.ndarray, size: int) -> np.ndarray:
    """Mean of each ``size`` consecutive rows along axis -2 (``len - size + 1`` of them).

    The sum runs as scipy.ndimage's ``uniform_filter1d`` runs it: a first sum in order, then one value
    added and one dropped per step, each sum divided by ``size``; so the numbers are scipy's bit for bit
    (a test compares them) without scipy: ``toolpath smooth`` needs only NumPy.
    """
    if values.shape[-2] < size:
        raise ValueError(f"{values.shape[-2]} rows are fewer than the {size} the mean needs")
    first = np.zeros(values.shape[:-2] + values.shape[-1:])
    for k in range(size):  # in order, as scipy's first sum
        first = first + values[..., k, :]
    steps = values[..., size:, :] - values[..., :-size, :]
    return np.cumsum(np.concatenate([first[..., None, :], steps], axis=-2), axis=-2) / float(size)


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
        # scipy's filter of the padded window, kept where the whole width lies inside it, opened its running
        # sum on `half` copies of the first row ("nearest"); the same sum from there gives the same bits
        edge = np.repeat(padded[..., :1, :], half, axis=-2)
        smoothed = running_mean(np.concatenate([edge, padded], axis=-2), width)[..., half:, :]
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
    binomial = np.array([float(math.comb(degree, i)) for i in k])
    return binomial * t[:, None] ** k * (1.0 - t[:, None]) ** (degree - k)


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
