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
        j = np.clip(np.arange(n - 1)[:, None] + np.arange(-BAND + 1, BAND + 1)[None, :], 1, n - 2)  # (n-1, 2 BAND)
        self.j_arc, self.jx, self.jy = self.arc[j], w[j, 0], w[j, 1]
        self.distinct = np.concatenate([np.ones_like(j[:, :1], dtype=bool), j[:, 1:] != j[:, :-1]], axis=1)
        self._kernels = _kernels()

    def _stack(self, points: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(points, dtype=np.float64).reshape(-1, *self.window.shape)

    def feet(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest point ``Q_i`` (x and y, each (..., n - 2)) on the band of original segments for every
        interior point of candidates ``points`` (..., n, 2), and its arc parameter (..., n - 2)."""
        lead = np.shape(points)[:-2]
        qx, qy, s = self._kernels.feet(self._stack(points), self.ax, self.ay, self.ux, self.uy, self.inverse,
                                       self.band_arc, self.band_length)
        return qx.reshape(*lead, -1), qy.reshape(*lead, -1), s.reshape(*lead, -1)

    def repair(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every interior point farther than the tolerance from its foot pulled onto the tube's rim
        (condition 1 of the module docstring), and the feet's arc parameters (a point moved towards its
        nearest foot keeps it, so they hold for the result)."""
        out = np.array(points, dtype=np.float64, copy=True)
        flat = out.reshape(-1, *self.window.shape)  # a view: the kernel repairs ``out`` in place
        qx, qy, s = self._kernels.feet(flat, self.ax, self.ay, self.ux, self.uy, self.inverse, self.band_arc,
                                       self.band_length)
        self._kernels.repair(flat, qx, qy, self.tolerance * _INSIDE)
        return out, s.reshape(*out.shape[:-2], -1)

    def certified(self, points: np.ndarray, s_inner: np.ndarray | None = None) -> np.ndarray:
        """Conditions 1-3 of the module docstring for candidates (..., n, 2); boolean (...,).
        ``s_inner``: the feet's arc parameters when :meth:`repair` gave them."""
        lead = np.shape(points)[:-2]
        flat = self._stack(points)
        tol2 = self.tolerance * self.tolerance
        if s_inner is None:
            qx, qy, s_inner = self._kernels.feet(flat, self.ax, self.ay, self.ux, self.uy, self.inverse,
                                                 self.band_arc, self.band_length)
            dx, dy = flat[:, 1:-1, 0] - qx, flat[:, 1:-1, 1] - qy
            near = (dx * dx + dy * dy).max(axis=-1, initial=0.0) <= tol2
        else:  # repaired: every point is on or inside the rim around its foot
            near = np.ones(len(flat), dtype=bool)
        s_flat = np.ascontiguousarray(s_inner, dtype=np.float64).reshape(len(flat), len(self.window) - 2)
        ok = self._kernels.certified(flat, s_flat, near, float(self.arc[-1]), self.j_arc, self.jx, self.jy,
                                     self.distinct, tol2)
        return ok.reshape(lead)

    def feasible(self, points: np.ndarray, s_inner: np.ndarray | None = None) -> np.ndarray:
        """Certified by the tube matching or by the discs (pairing each point with its own original place
        is a matching too, but the nearest-foot matching need not find it)."""
        return self.certified(points, s_inner) | within_discs(points, self.window, self.tolerance)


def _kernels():
    """The compiled loops (numba, a ``pipeline`` extra: only the research pipeline runs the tube)."""
    try:
        from toolpath.smoothing import tube_kernels
    except ImportError as exc:  # the core install: ``toolpath smooth`` holds the discs, never the tube
        raise RuntimeError("the tube fidelity mode needs numba: pip install 'toolpath-lab[pipeline]'") from exc
    return tube_kernels


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
