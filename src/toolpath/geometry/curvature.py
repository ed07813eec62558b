"""LocalCurvature and the smoothing objective of Li et al. (Sensors 2024), batched over windows.

Every function takes points of shape (..., n, 2) (any leading batch shape) and works in float64.
Repeated points (zero-length segments) have no direction: drop them first with
:func:`drop_repeated`, as the labeller does.  Where one reaches these functions anyway, its
turning term counts as 0 (no turn) instead of NaN.
"""

from __future__ import annotations

import numpy as np


def segment_vectors(points: np.ndarray) -> np.ndarray:
    """``v_i = P_{i+1} - P_i`` (Sec. 4.1), shape (..., n-1, 2)."""
    p = np.asarray(points, dtype=np.float64)
    return p[..., 1:, :] - p[..., :-1, :]


def turning_cosines(points: np.ndarray) -> np.ndarray:
    """Cosine between consecutive segment vectors, Eq. 1 over Eq. 2 products; shape (..., n-2).

    A term with a zero-length segment is 1 (counted as no turn).
    """
    p = np.asarray(points, dtype=np.float64)
    # per coordinate rather than einsum / linalg.norm over an axis of 2: several times faster
    vx, vy = np.diff(p[..., 0], axis=-1), np.diff(p[..., 1], axis=-1)
    dot = vx[..., 1:] * vx[..., :-1] + vy[..., 1:] * vy[..., :-1]  # Eq. 1
    norm = np.sqrt(vx * vx + vy * vy)  # Eq. 2
    denom = norm[..., 1:] * norm[..., :-1]
    safe = np.where(denom > 0.0, denom, 1.0)
    cos = np.where(denom > 0.0, dot / safe, 1.0)
    return np.clip(cos, -1.0, 1.0)


def local_curvature(points: np.ndarray) -> np.ndarray:
    """LocalCurvature, Eq. 3 (and Eq. 6-7): ``sum_{i=1}^{n-2} (1 - cos(v_i, v_{i-1}))``.

    A 50-point window has 48 terms.  A straight line gives 0, one right-angle corner 1, a full
    reversal 2.  Shape (...,).
    """
    return np.sum(1.0 - turning_cosines(points), axis=-1)


def smoothness_penalty(points: np.ndarray) -> np.ndarray:
    """SmoothnessPenalty, Eq. 8-9: ``sum_{i=2}^{n-1} ||P_{i+1} - 2 P_i + P_{i-1}||``, shape (...,)."""
    p = np.asarray(points, dtype=np.float64)
    sx = p[..., 2:, 0] - 2.0 * p[..., 1:-1, 0] + p[..., :-2, 0]
    sy = p[..., 2:, 1] - 2.0 * p[..., 1:-1, 1] + p[..., :-2, 1]
    return np.sqrt(sx * sx + sy * sy).sum(axis=-1)


def fitness(points: np.ndarray) -> np.ndarray:
    """Fitness, Eq. 10: LocalCurvature + SmoothnessPenalty, shape (...,)."""
    return local_curvature(points) + smoothness_penalty(points)


def arc_length(points: np.ndarray) -> np.ndarray:
    """Polyline length, shape (...,)."""
    return np.linalg.norm(segment_vectors(points), axis=-1).sum(axis=-1)


def drop_repeated(points: np.ndarray, tolerance: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Remove points within ``tolerance`` of their predecessor (one path, shape (n, d)).

    Returns the kept points and the boolean mask of kept indices (the first point is always kept).
    """
    p = np.asarray(points)
    if len(p) == 0:
        return p, np.zeros(0, dtype=bool)
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    keep = np.concatenate([[True], step > tolerance])
    return p[keep], keep


def reduction_pct(before: float, after: float) -> float:
    """Curvature reduction in per cent (0 for a window that had no curvature to remove)."""
    return 100.0 * (1.0 - after / before) if before > 0 else 0.0
