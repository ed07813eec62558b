"""How far points stray from a path: point-to-polyline distances, batched (the two-sided distance
between two paths is :mod:`toolpath.geometry.hausdorff`)."""

from __future__ import annotations

import numpy as np


def point_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """Distance from each point to the nearest point of a polyline.

    Parameters
    ----------
    points : (..., n, 2)
    polyline : (..., m, 2) with m >= 1; the batch shapes must broadcast.

    Returns
    -------
    (..., n) distances.
    """
    p = np.asarray(points, dtype=np.float64)[..., :, None, :]  # (..., n, 1, 2)
    q = np.asarray(polyline, dtype=np.float64)
    if q.shape[-2] == 1:
        return np.linalg.norm(p[..., 0, :] - q, axis=-1)
    a = q[..., None, :-1, :]  # (..., 1, m-1, 2)
    ab = q[..., None, 1:, :] - a
    length2 = np.einsum("...k,...k->...", ab, ab)
    t = np.einsum("...k,...k->...", p - a, ab) / np.where(length2 > 0, length2, 1.0)
    t = np.clip(np.where(length2 > 0, t, 0.0), 0.0, 1.0)
    nearest = a + t[..., None] * ab
    return np.linalg.norm(p - nearest, axis=-1).min(axis=-1)
