"""The smoothing problem every method solves (Li et al. 2024, Sec. 4.2, plus bounded deviation).

A window's interior points move, its two end points stay.  The decision vector of every optimiser
is the flattened interior displacement, shape ``(2 (n - 2),)``, so all methods search one space.
Objective: Fitness (Eq. 10) = LocalCurvature (Eq. 3) + SmoothnessPenalty (Eq. 8-9), plus a fidelity
mode: ``none`` (the paper, literally), ``penalty`` (``weight`` x the largest distance of a point
from the polyline segments near its original place) or ``bound`` (every point within ``tolerance`` of the original
polyline, enforced as a hard constraint by projecting candidates onto that tube).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolpath.geometry.curvature import fitness

MODES = ("none", "penalty", "bound")


def _project_onto_segments(p: np.ndarray, a: np.ndarray, b: np.ndarray, tolerance: float) -> np.ndarray:
    """Project ``p`` (..., n, 2) into the union of the ``tolerance`` tubes of segments ``a``-``b``.

    ``a`` and ``b`` broadcast against ``p[..., None, :]`` as (..., n, m, 2): m candidate segments per
    point.  The nearest point of the union lies on the line to the nearest segment point, so this is
    the exact Euclidean projection onto that union.
    """
    ab = b - a
    length2 = np.maximum(np.einsum("...k,...k->...", ab, ab), 1e-300)
    t = np.clip(np.einsum("...k,...k->...", p[..., None, :] - a, ab) / length2, 0.0, 1.0)
    nearest_all = a + t[..., None] * ab  # (..., n, m, 2)
    dist_all = np.linalg.norm(p[..., None, :] - nearest_all, axis=-1)
    k = dist_all.argmin(axis=-1)
    nearest = np.take_along_axis(nearest_all, k[..., None, None].repeat(2, axis=-1), axis=-2)[..., 0, :]
    dist = np.take_along_axis(dist_all, k[..., None], axis=-1)[..., 0]
    scale = np.where(dist > tolerance, tolerance / np.maximum(dist, 1e-300), 1.0)
    return nearest + (p - nearest) * scale[..., None]


def project_to_tube(points: np.ndarray, polyline: np.ndarray, tolerance: float) -> np.ndarray:
    """Move every point farther than ``tolerance`` from ``polyline`` onto the tube's boundary.

    Exact Euclidean projection onto the whole tube.  ``points`` (..., n, 2), ``polyline`` (m, 2).
    """
    p = np.asarray(points, dtype=np.float64)
    return _project_onto_segments(p, polyline[:-1], polyline[1:], tolerance)


def _near_segments(polyline: np.ndarray, reach: int) -> np.ndarray:
    """Indices of the ``2 reach`` segments around every interior point, clipped at the ends, (n-2, 2 reach)."""
    n = len(polyline)
    seg = np.arange(1, n - 1)[:, None] + np.arange(-reach, reach)[None, :]
    return np.clip(seg, 0, n - 2)  # duplicate segments at the ends change nothing


def project_interior_near(points: np.ndarray, polyline: np.ndarray, tolerance: float, reach: int) -> np.ndarray:
    """Project interior point ``i`` (row ``i - 1`` of ``points`` (..., n - 2, 2)) into the tubes of the
    ``2 reach`` polyline segments around its original index ``i`` (``reach = 1``: its own two segments).

    A point within ``tolerance`` of some segment is within ``tolerance`` of the polyline, so the
    bound holds exactly; restricting each point to its own neighbourhood is a (slightly) smaller
    feasible set that also keeps the points in order along the path, and costs ``O(n reach)``
    instead of ``O(n^2)`` (0.47 s for 1000 windows of 50 points against the whole tube).
    """
    seg = _near_segments(polyline, reach)
    return _project_onto_segments(np.asarray(points, dtype=np.float64), polyline[seg], polyline[seg + 1], tolerance)


class _NearTube:
    """:func:`project_interior_near` with the segment geometry computed once per window, written out
    per coordinate: the optimisers project every candidate of every generation through it."""

    def __init__(self, polyline: np.ndarray, reach: int) -> None:
        seg = _near_segments(polyline, reach)
        a, b = polyline[seg], polyline[seg + 1]
        self.ax, self.ay = a[..., 0], a[..., 1]
        self.abx, self.aby = b[..., 0] - self.ax, b[..., 1] - self.ay
        self.inv_len2 = 1.0 / np.maximum(self.abx**2 + self.aby**2, 1e-300)

    def nearest(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest points on the near segments (x, y) and the squared distance, each (..., n-2)."""
        px, py = points[..., 0:1], points[..., 1:2]
        t = np.clip(((px - self.ax) * self.abx + (py - self.ay) * self.aby) * self.inv_len2, 0.0, 1.0)
        nx, ny = self.ax + t * self.abx, self.ay + t * self.aby
        d2 = (px - nx) ** 2 + (py - ny) ** 2
        if d2.shape[-1] == 2:  # reach 1, the default: a comparison is cheaper than argmin + gather
            first = d2[..., 0] <= d2[..., 1]
            return (np.where(first, nx[..., 0], nx[..., 1]), np.where(first, ny[..., 0], ny[..., 1]),
                    np.where(first, d2[..., 0], d2[..., 1]))
        k = d2.argmin(axis=-1)[..., None]
        return tuple(np.take_along_axis(v, k, axis=-1)[..., 0] for v in (nx, ny, d2))

    def project(self, points: np.ndarray, tolerance: float) -> np.ndarray:
        nx, ny, d2 = self.nearest(points)
        dist = np.sqrt(d2)
        scale = np.where(dist > tolerance, tolerance / np.maximum(dist, 1e-300), 1.0)
        out = np.empty_like(points)
        out[..., 0] = nx + (points[..., 0] - nx) * scale
        out[..., 1] = ny + (points[..., 1] - ny) * scale
        return out

    def distance(self, points: np.ndarray) -> np.ndarray:
        return np.sqrt(self.nearest(points)[2])


@dataclass(frozen=True)
class SmoothingProblem:
    """One window to smooth.  ``window`` (n, 2) in mm; fields as in ``conf/optimize``."""

    window: np.ndarray
    mode: str = "bound"
    tolerance: float = 0.05
    weight: float = 10.0
    reach: int = 1

    def __post_init__(self) -> None:
        object.__setattr__(self, "window", np.asarray(self.window, dtype=np.float64))
        object.__setattr__(self, "_tube", _NearTube(self.window, self.reach))
        if self.mode not in MODES:
            raise ValueError(f"fidelity mode {self.mode!r} is not one of {MODES}")
        if len(self.window) < 3:
            raise ValueError("a window needs at least 3 points")

    @property
    def dimension(self) -> int:
        return 2 * (len(self.window) - 2)

    def points(self, x: np.ndarray, project: bool = True) -> np.ndarray:
        """Windows for decision vectors ``x`` (..., dimension); ``bound`` mode projects them unless
        ``project`` is false (for candidates that are feasible already)."""
        x = np.asarray(x, dtype=np.float64)
        pts = np.broadcast_to(self.window, (*x.shape[:-1], *self.window.shape)).copy()
        pts[..., 1:-1, :] += x.reshape(*x.shape[:-1], -1, 2)
        if project and self.mode == "bound":
            pts[..., 1:-1, :] = self._tube.project(pts[..., 1:-1, :], self.tolerance)
        return pts

    def objective(self, x: np.ndarray) -> np.ndarray:
        """Eq. 10 of each candidate, plus the deviation penalty in ``penalty`` mode; shape (...,)."""
        return self.score(self.points(x))

    def score(self, pts: np.ndarray) -> np.ndarray:
        """The objective of candidate windows given as points (..., n, 2), already feasible."""
        value = fitness(pts)
        if self.mode == "penalty":
            value = value + self.weight * self._tube.distance(pts[..., 1:-1, :]).max(axis=-1)
        return value

    def displacement(self, points: np.ndarray) -> np.ndarray:
        """The decision vector that yields ``points`` (the inverse of :meth:`points` before projection)."""
        return (np.asarray(points)[..., 1:-1, :] - self.window[1:-1]).reshape(*np.shape(points)[:-2], -1)
