"""The smoothing problem every method solves (Li et al. 2024, Sec. 4.2, plus bounded deviation).

A window's interior points move, its two end points stay.  The decision vector of every optimiser
is the flattened interior displacement, shape ``(2 (n - 2),)``, so all methods search one space.
Objective: Fitness (Eq. 10) = LocalCurvature (Eq. 3) + SmoothnessPenalty (Eq. 8-9), plus a fidelity
mode: ``none`` (the paper, literally), ``penalty`` (``weight`` x the largest distance of a point
from the original polyline) or ``bound`` (every point within ``tolerance`` of the original
polyline, enforced as a hard constraint by projecting candidates onto that tube).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolpath.geometry.curvature import fitness
from toolpath.geometry.deviation import point_to_polyline

MODES = ("none", "penalty", "bound")


def project_to_tube(points: np.ndarray, polyline: np.ndarray, tolerance: float) -> np.ndarray:
    """Move every point farther than ``tolerance`` from ``polyline`` onto the tube's boundary.

    The nearest point of the tube is along the line to the nearest polyline point, so this is the
    exact Euclidean projection.  ``points`` (..., n, 2), ``polyline`` (m, 2).
    """
    p = np.asarray(points, dtype=np.float64)
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    length2 = np.maximum((ab * ab).sum(axis=1), 1e-300)
    # (p - a) . ab for every point and segment, as a parameter along the segment clipped to it
    t = np.clip((np.einsum("...nk,mk->...nm", p, ab) - (a * ab).sum(axis=1)) / length2, 0.0, 1.0)
    nearest_all = a + t[..., None] * ab  # (..., n, m, 2)
    dist_all = np.linalg.norm(p[..., None, :] - nearest_all, axis=-1)
    k = dist_all.argmin(axis=-1)
    nearest = np.take_along_axis(nearest_all, k[..., None, None].repeat(2, axis=-1), axis=-2)[..., 0, :]
    dist = np.take_along_axis(dist_all, k[..., None], axis=-1)[..., 0]
    scale = np.where(dist > tolerance, tolerance / np.maximum(dist, 1e-300), 1.0)
    return nearest + (p - nearest) * scale[..., None]


@dataclass(frozen=True)
class SmoothingProblem:
    """One window to smooth.  ``window`` (n, 2) in mm; fields as in ``conf/optimize``."""

    window: np.ndarray
    mode: str = "bound"
    tolerance: float = 0.05
    weight: float = 10.0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"fidelity mode {self.mode!r} is not one of {MODES}")
        if len(self.window) < 3:
            raise ValueError("a window needs at least 3 points")

    @property
    def dimension(self) -> int:
        return 2 * (len(self.window) - 2)

    def points(self, x: np.ndarray) -> np.ndarray:
        """Windows for decision vectors ``x`` (..., dimension); ``bound`` mode projects them."""
        x = np.asarray(x, dtype=np.float64)
        pts = np.broadcast_to(self.window, (*x.shape[:-1], *self.window.shape)).copy()
        pts[..., 1:-1, :] += x.reshape(*x.shape[:-1], -1, 2)
        if self.mode == "bound":
            pts[..., 1:-1, :] = project_to_tube(pts[..., 1:-1, :], self.window, self.tolerance)
        return pts

    def objective(self, x: np.ndarray) -> np.ndarray:
        """Eq. 10 of each candidate, plus the deviation penalty in ``penalty`` mode; shape (...,)."""
        pts = self.points(x)
        value = fitness(pts)
        if self.mode == "penalty":
            value = value + self.weight * point_to_polyline(pts, self.window).max(axis=-1)
        return value

    def displacement(self, points: np.ndarray) -> np.ndarray:
        """The decision vector that yields ``points`` (the inverse of :meth:`points` before projection)."""
        return (np.asarray(points)[..., 1:-1, :] - self.window[1:-1]).reshape(*np.shape(points)[:-2], -1)
