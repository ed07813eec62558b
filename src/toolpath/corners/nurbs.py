"""Planar NURBS curves (the NURBS corner paper, Eq. 1-6) on scipy's B-splines.

A NURBS curve is the projection of a B-spline in homogeneous coordinates (w x, w y, w) (Eq. 1);
scipy's ``BSpline`` evaluates the basis of Eq. 2 and its derivatives (Eq. 3-4), and the quotient
rule gives C' and C'' (Eq. 5) and the radius of curvature rho = |C'|^3 / |C' x C''| (Eq. 6).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline


def clamped_uniform_knots(count: int, degree: int) -> np.ndarray:
    """Knots of a clamped curve with ``count`` control points: degree + 1 zeros and ones, uniform inside."""
    inner = np.linspace(0.0, 1.0, count - degree + 1)[1:-1]
    return np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)])


@dataclass(frozen=True)
class Nurbs:
    """Control points (n, 2), weights (n,), degree; clamped uniform knots on [0, 1] unless ``knots``
    is given (e.g. a piecewise Bezier curve, whose inner knots repeat ``degree`` times)."""

    points: np.ndarray
    weights: np.ndarray
    degree: int = 3
    knots: tuple[float, ...] | None = None

    def knot_vector(self) -> np.ndarray:
        if self.knots is not None:
            return np.asarray(self.knots, dtype=float)
        return clamped_uniform_knots(len(self.weights), self.degree)

    def _homogeneous(self) -> BSpline:
        w = np.asarray(self.weights, dtype=float)
        coef = np.c_[np.asarray(self.points, dtype=float) * w[:, None], w]
        return BSpline(self.knot_vector(), coef, self.degree)

    def derivatives(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """C(u), C'(u), C''(u) (Eq. 1 and 5), each (len(u), 2)."""
        spline = self._homogeneous()
        h, h1, h2 = spline(u), spline(u, 1), spline(u, 2)  # works across repeated inner knots too
        w, w1, w2 = h[:, 2:], h1[:, 2:], h2[:, 2:]
        c = h[:, :2] / w
        c1 = (h1[:, :2] - c * w1) / w
        c2 = (h2[:, :2] - 2 * c1 * w1 - c * w2) / w
        return c, c1, c2

    def __call__(self, u: np.ndarray) -> np.ndarray:
        return self.derivatives(np.atleast_1d(np.asarray(u, dtype=float)))[0]

    def radius(self, u: np.ndarray) -> np.ndarray:
        """Radius of curvature rho(u) = |C'|^3 / |C' x C''| (Eq. 6); inf where the curve is straight."""
        _, c1, c2 = self.derivatives(np.atleast_1d(np.asarray(u, dtype=float)))
        cross = np.abs(c1[:, 0] * c2[:, 1] - c1[:, 1] * c2[:, 0])
        speed = np.hypot(c1[:, 0], c1[:, 1])
        with np.errstate(divide="ignore"):
            return np.where(cross > 1e-15 * np.maximum(speed, 1e-300) ** 3, speed**3 / cross, np.inf)

    def basis(self, u: float) -> np.ndarray:
        """N_{i,p}(u) of every control point (Eq. 2), at one parameter."""
        count = len(self.weights)
        eye = np.eye(count)
        knots = self.knot_vector()
        return np.array([BSpline(knots, eye[k], self.degree)(u) for k in range(count)])
