"""The smoothing problem every method solves (Li et al. 2024, Sec. 4.2, plus bounded deviation).

A window's interior points move, its two end points stay.  The decision vector of every optimiser
is the flattened interior displacement, shape ``(2 (n - 2),)``, so all methods search one space.
Objective: Fitness (Eq. 10) = LocalCurvature (Eq. 3) + SmoothnessPenalty (Eq. 8-9), plus a fidelity
mode: ``none`` (the paper, literally), ``penalty`` (``weight`` x the largest displacement of a point),
``bound`` (every point within ``tolerance`` of its own place: the disc bound) or ``tube`` (the window
within ``tolerance`` of the original both ways, points free to slide along it: :mod:`toolpath.smoothing.tube`).

``bound`` is exact because it bounds each point's *displacement*: every candidate is projected onto
the product of discs ``|P'_i - P_i| <= tolerance`` (the Euclidean projection: a point outside its disc
moves to the disc's rim along the line to its centre).  Then segment ``P'_i P'_{i+1}`` and segment
``P_i P_{i+1}`` pair up point for point, ``|((1-t) P'_i + t P'_{i+1}) - ((1-t) P_i + t P_{i+1})| <=
(1-t) |P'_i - P_i| + t |P'_{i+1} - P_{i+1}| <= tolerance``, so the Frechet distance, and with it the
two-sided Hausdorff distance of :func:`toolpath.geometry.hausdorff`, is at most ``tolerance``, with the
points in their order along the path and the end points fixed.  (The earlier rule, each point within
``tolerance`` of its own two segments, let points slide along a segment and cut a corner by up to
2.8 mm.)  The price is that a noise spike taller than the tolerance can only be lowered by it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolpath.geometry.curvature import fitness
from toolpath.smoothing import tube

MODES = ("none", "penalty", "bound", "tube")
BOUNDED = ("bound", "tube")  # the modes whose results are held within the tolerance
# added to the objective of a tube candidate the matching cannot certify: never accepted over a
# certified one (the first population is certified), finite so that swarm arithmetic stays finite
INFEASIBLE = 1.0e3
# a hair inside the disc, so rounding in the projection never lands a point outside the tolerance
_INSIDE = 1.0 - 1e-12


def clip_displacement(displacement: np.ndarray, tolerance: float) -> np.ndarray:
    """Project displacements (..., 2) onto the disc of radius ``tolerance`` (the ``bound`` mode's
    feasible set, point by point)."""
    d = np.asarray(displacement, dtype=np.float64)
    length = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)
    limit = tolerance * _INSIDE
    scale = np.where(length > limit, limit / np.maximum(length, 1e-300), 1.0)
    return d * scale[..., None]


@dataclass(frozen=True)
class SmoothingProblem:
    """One window to smooth.  ``window`` (n, 2) in mm; fields as in ``conf/optimize``."""

    window: np.ndarray
    mode: str = "bound"
    tolerance: float = 0.05
    weight: float = 10.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "window", np.asarray(self.window, dtype=np.float64))
        if not self.tolerance > 0:
            raise ValueError(f"the tolerance must be positive, got {self.tolerance}")
        if self.mode not in MODES:
            raise ValueError(f"fidelity mode {self.mode!r} is not one of {MODES}")
        if len(self.window) < 3:
            raise ValueError("a window needs at least 3 points")
        # the tube's geometry, and the feet of the last candidates it repaired (reused by :meth:`score`)
        object.__setattr__(self, "_tube", tube.Tube(self.window, self.tolerance) if self.mode == "tube" else None)
        object.__setattr__(self, "_repaired", (None, None))

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
            pts[..., 1:-1, :] = self.window[1:-1] + clip_displacement(pts[..., 1:-1, :] - self.window[1:-1],
                                                                      self.tolerance)
        elif project and self.mode == "tube":
            pts, feet = self._tube.repair(pts)
            object.__setattr__(self, "_repaired", (pts, feet))
        return pts

    def objective(self, x: np.ndarray) -> np.ndarray:
        """Eq. 10 of each candidate, plus the deviation penalty in ``penalty`` mode; shape (...,)."""
        return self.score(self.points(x))

    def score(self, pts: np.ndarray) -> np.ndarray:
        """The objective of candidate windows given as points (..., n, 2), already feasible."""
        value = fitness(pts)
        if self.mode == "penalty":
            # the largest displacement bounds the two-sided distance (see the module docstring)
            moved = pts[..., 1:-1, :] - self.window[1:-1]
            value = value + self.weight * np.sqrt(moved[..., 0] ** 2 + moved[..., 1] ** 2).max(axis=-1)
        elif self.mode == "tube":
            last, feet = self._repaired
            ok = self._tube.feasible(pts, feet if pts is last else None)
            value = value + np.where(ok, 0.0, INFEASIBLE)
        return value

    def displacement(self, points: np.ndarray) -> np.ndarray:
        """The decision vector that yields ``points`` (the inverse of :meth:`points` before projection)."""
        return (np.asarray(points)[..., 1:-1, :] - self.window[1:-1]).reshape(*np.shape(points)[:-2], -1)


class ProblemBatch:
    """Several problems of one window length, mode and tolerance solved together: every array gains a
    leading window axis, so one NumPy call serves the whole batch (the same arithmetic, element by
    element, as each :class:`SmoothingProblem` alone).  Decision vectors are (W, ..., dimension)."""

    def __init__(self, problems: list[SmoothingProblem]) -> None:
        first = problems[0]
        if any((p.window.shape, p.mode, p.tolerance, p.weight) != (first.window.shape, first.mode, first.tolerance,
                                                                   first.weight) for p in problems):
            raise ValueError("problems solved together need one window length, mode, tolerance and weight")
        self.windows = np.stack([p.window for p in problems])[:, None]  # (W, 1, n, 2)
        self.mode, self.tolerance, self.weight = first.mode, first.tolerance, first.weight
        self.dimension = first.dimension
        self.tubes = [p._tube for p in problems]
        self._repaired: tuple = (None, None)

    def points(self, x: np.ndarray, project: bool = True) -> np.ndarray:
        """:meth:`SmoothingProblem.points` of decision vectors (W, pop, dimension)."""
        pts = np.broadcast_to(self.windows, (*x.shape[:-1], *self.windows.shape[-2:])).copy()
        pts[..., 1:-1, :] += x.reshape(*x.shape[:-1], -1, 2)
        if project and self.mode == "bound":
            inner = self.windows[..., 1:-1, :]
            pts[..., 1:-1, :] = inner + clip_displacement(pts[..., 1:-1, :] - inner, self.tolerance)
        elif project and self.mode == "tube":
            feet = []
            for k, shape_tube in enumerate(self.tubes):
                pts[k], arc = shape_tube.repair(pts[k])
                feet.append(arc)
            self._repaired = (pts, feet)
        return pts

    def score(self, pts: np.ndarray, below: np.ndarray | None = None) -> np.ndarray:
        """:meth:`SmoothingProblem.score` of candidates (W, pop, n, 2).  ``below`` (W, pop): the values a
        caller will only compare them against (``score < below``, the greedy rule); a tube candidate whose
        Fitness is not below it is then left uncertified (no penalty can bring it below), which gives the
        same comparisons at a fraction of the cost, since the tube check is most of a generation's work."""
        value = fitness(pts)
        if self.mode == "penalty":
            moved = pts[..., 1:-1, :] - self.windows[..., 1:-1, :]
            value = value + self.weight * np.sqrt(moved[..., 0] ** 2 + moved[..., 1] ** 2).max(axis=-1)
        elif self.mode == "tube":
            last, feet = self._repaired
            for k, shape_tube in enumerate(self.tubes):
                todo = slice(None) if below is None else np.flatnonzero(value[k] < below[k])
                ok = shape_tube.feasible(pts[k][todo], feet[k][todo] if pts is last else None)
                value[k][todo] += np.where(ok, 0.0, INFEASIBLE)
        return value

    def displacement(self, points: np.ndarray) -> np.ndarray:
        return (points[..., 1:-1, :] - self.windows[..., 1:-1, :]).reshape(*points.shape[:-2], -1)
