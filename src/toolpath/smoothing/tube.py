"""The ``tube`` fidelity mode: a smoothed window within ``tolerance`` of the original both ways, points
free to slide along the path (the two-sided band a machinist means, with the end points fixed).

The disc bound of :mod:`toolpath.smoothing.problem` keeps every point within ``tolerance`` of its
own original place; that is sufficient but stricter than the band: a sharp corner cannot be rounded
by points sliding towards it.  Here a candidate is accepted when a *matching* certifies it:

1. every new point ``P'_i`` is paired with its foot ``Q_i`` on the original path near its own place
   (segments ``i - BAND .. i + BAND - 1``), ``|P'_i - Q_i| <= tolerance``, the ends with the ends;
2. the feet run forward along the path (arc parameters ``s_i`` non-decreasing);
3. every original vertex ``V_j`` strictly between ``Q_i`` and ``Q_{i+1}`` is within ``tolerance`` of
   the new segment ``P'_i P'_{i+1}``, at feet ordered along that segment.

Then the matched points cut both polylines into pieces that are straight on both sides and whose
ends are within ``tolerance`` of each other, so linear interpolation pairs every point of one with a
point of the other within ``tolerance``: the Frechet distance, hence the two-sided Hausdorff distance,
is at most ``tolerance``.  The test is O(n) per candidate, so a whole population is checked every
generation; every accepted result is checked again by the exact Hausdorff distance in
:func:`toolpath.smoothing.methods.smooth`.  A disc-feasible window always passes (see
:func:`feasible`), so the tube only adds freedom.
"""

from __future__ import annotations

import numpy as np

BAND = 2  # a point's foot may lie on the two segments each side of its original place
_INSIDE = 1.0 - 1e-9  # the repair lands a hair inside the tube, so rounding never leaves it


class Tube:
    """The tube around one original ``window`` (n, 2): its geometry computed once, so that a whole
    population, or a single candidate from a swarm library, is repaired and certified cheaply."""

    def __init__(self, window: np.ndarray, tolerance: float) -> None:
        w = np.asarray(window, dtype=np.float64)
        n = len(w)
        self.window, self.tolerance = w, float(tolerance)
        direction = np.diff(w, axis=0)
        length = np.sqrt(direction[:, 0] ** 2 + direction[:, 1] ** 2)
        self.arc = np.concatenate([[0.0], np.cumsum(length)])
        band = np.clip(np.arange(1, n - 1)[:, None] + np.arange(-BAND, BAND)[None, :], 0, n - 2)  # (n-2, 2 BAND)
        self.ax, self.ay = w[band, 0], w[band, 1]
        self.ux, self.uy = direction[band, 0], direction[band, 1]
        length2 = self.ux**2 + self.uy**2
        self.inverse = np.where(length2 > 0, 1.0 / np.where(length2 > 0, length2, 1.0), 0.0)
        self.band_arc, self.band_length = self.arc[band], np.sqrt(length2)
        # vertices j that may fall strictly between the feet of new points i and i + 1
        i = np.arange(n - 1)[:, None]
        j = np.clip(i + np.arange(-BAND + 1, BAND + 1)[None, :], 1, n - 2)  # (n-1, 2 BAND)
        self.i, self.j_arc, self.jx, self.jy = i, self.arc[j], w[j, 0], w[j, 1]
        self.distinct = np.concatenate([np.ones_like(j[:, :1], dtype=bool), j[:, 1:] != j[:, :-1]], axis=1)

    def feet(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest point ``Q_i`` (x and y, each (..., n - 2)) on the band of original segments for every
        interior point of candidates ``points`` (..., n, 2), and its arc parameter (..., n - 2)."""
        # per coordinate, not a sum over an axis of 2: NACOA calls this on the whole population each generation
        px, py = points[..., 1:-1, 0, None], points[..., 1:-1, 1, None]  # (..., n-2, 1)
        t = np.clip(((px - self.ax) * self.ux + (py - self.ay) * self.uy) * self.inverse, 0.0, 1.0)
        fx, fy = self.ax + t * self.ux, self.ay + t * self.uy
        best = ((px - fx) ** 2 + (py - fy) ** 2).argmin(axis=-1)[..., None]
        pick = lambda a: np.take_along_axis(a, best, axis=-1)[..., 0]  # noqa: E731
        return pick(fx), pick(fy), pick(self.band_arc + t * self.band_length)

    def repair(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every interior point farther than the tolerance from its foot pulled onto the tube's rim
        (condition 1 of the module docstring), and the feet's arc parameters (a point moved towards its
        nearest foot keeps it, so they hold for the result)."""
        out = np.array(points, dtype=np.float64, copy=True)
        qx, qy, s = self.feet(out)
        dx, dy = out[..., 1:-1, 0] - qx, out[..., 1:-1, 1] - qy
        length = np.sqrt(dx * dx + dy * dy)
        limit = self.tolerance * _INSIDE
        scale = np.where(length > limit, limit / np.maximum(length, 1e-300), 1.0)
        out[..., 1:-1, 0], out[..., 1:-1, 1] = qx + dx * scale, qy + dy * scale
        return out, s

    def certified(self, points: np.ndarray, s_inner: np.ndarray | None = None) -> np.ndarray:
        """Conditions 1-3 of the module docstring for candidates (..., n, 2); boolean (...,).
        ``s_inner``: the feet's arc parameters when :meth:`repair` gave them."""
        tol2 = self.tolerance * self.tolerance
        if s_inner is None:
            qx, qy, s_inner = self.feet(points)
            dx, dy = points[..., 1:-1, 0] - qx, points[..., 1:-1, 1] - qy
            near = (dx * dx + dy * dy).max(axis=-1, initial=0.0) <= tol2
        else:  # repaired: every point is on or inside the rim around its foot
            near = np.ones(points.shape[:-2], dtype=bool)
        lead = points.shape[:-2]
        s = np.concatenate([np.zeros((*lead, 1)), s_inner, np.full((*lead, 1), self.arc[-1])], axis=-1)
        forward = (np.diff(s, axis=-1) >= 0).all(axis=-1)
        i = self.i
        inside = (self.j_arc > s[..., i]) & (self.j_arc < s[..., i + 1]) & self.distinct  # (..., n-1, 2 BAND)
        ax, ay = points[..., :-1, 0, None], points[..., :-1, 1, None]
        ux, uy = points[..., 1:, 0, None] - ax, points[..., 1:, 1, None] - ay
        vx, vy = self.jx - ax, self.jy - ay
        length2 = ux * ux + uy * uy
        t = np.clip((vx * ux + vy * uy) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
        close = np.where(inside, (vx - t * ux) ** 2 + (vy - t * uy) ** 2 <= tol2, True).all(axis=(-2, -1))
        # the feet of the inside vertices along a new segment must not run backwards
        running = np.maximum.accumulate(np.where(inside, t, -np.inf), axis=-1)
        ordered = np.where(inside, t >= running, True).all(axis=(-2, -1))
        return near & forward & close & ordered

    def feasible(self, points: np.ndarray, s_inner: np.ndarray | None = None) -> np.ndarray:
        """Certified by the tube matching or by the discs (pairing each point with its own original place
        is a matching too, but the nearest-foot matching need not find it)."""
        return self.certified(points, s_inner) | within_discs(points, self.window, self.tolerance)


def repair(points: np.ndarray, window: np.ndarray, tolerance: float) -> np.ndarray:
    """:meth:`Tube.repair`'s points."""
    return Tube(window, tolerance).repair(points)[0]


def tube_certified(points: np.ndarray, window: np.ndarray, tolerance: float) -> np.ndarray:
    """:meth:`Tube.certified`."""
    return Tube(window, tolerance).certified(np.asarray(points, dtype=np.float64))


def within_discs(points: np.ndarray, window: np.ndarray, tolerance: float) -> np.ndarray:
    """Every point within ``tolerance`` of its own original place (the disc bound's certificate)."""
    d = np.asarray(points)[..., 1:-1, :] - np.asarray(window)[1:-1]
    return (d[..., 0] ** 2 + d[..., 1] ** 2).max(axis=-1, initial=0.0) <= tolerance * tolerance


def feasible(points: np.ndarray, window: np.ndarray, tolerance: float) -> np.ndarray:
    """:meth:`Tube.feasible`: certified within the two-sided ``tolerance`` by the tube or the discs."""
    return Tube(window, tolerance).feasible(np.asarray(points, dtype=np.float64))
