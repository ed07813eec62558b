"""Compiled loops of :class:`toolpath.smoothing.tube.Tube` (numba): the feet, the repair and the
matching certificate of a stack of candidate windows.

The tube check is most of NACOA's work in ``tube`` mode (a population of 1,000 windows every
generation) and of every swarm baseline's single-candidate objective; as NumPy array expressions it
builds some forty (population, n, 4) temporaries a call.  These loops do the same arithmetic, operation
for operation, one candidate at a time, and stop a candidate at its first failed condition.  numba is a
``pipeline`` extra: only the research pipeline runs the tube (``toolpath smooth`` holds the discs).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def feet(points, ax, ay, ux, uy, inverse, band_arc, band_length):  # pragma: no cover - compiled
    """Nearest point on the band of original segments of every interior point: x, y and arc parameter,
    each (P, n - 2), for candidates ``points`` (P, n, 2); the first nearest wins, as NumPy's argmin."""
    count, n = points.shape[0], points.shape[1]
    width = ax.shape[1]
    qx = np.empty((count, n - 2))
    qy = np.empty((count, n - 2))
    s = np.empty((count, n - 2))
    for p in range(count):
        for i in range(n - 2):
            px, py = points[p, i + 1, 0], points[p, i + 1, 1]
            best = np.inf
            for c in range(width):
                t = ((px - ax[i, c]) * ux[i, c] + (py - ay[i, c]) * uy[i, c]) * inverse[i, c]
                t = min(max(t, 0.0), 1.0)
                fx, fy = ax[i, c] + t * ux[i, c], ay[i, c] + t * uy[i, c]
                d2 = (px - fx) ** 2 + (py - fy) ** 2
                if c == 0 or d2 < best:
                    best = d2
                    qx[p, i], qy[p, i], s[p, i] = fx, fy, band_arc[i, c] + t * band_length[i, c]
    return qx, qy, s


@njit(cache=True)
def repair(points, qx, qy, limit):  # pragma: no cover - compiled
    """Interior points farther than ``limit`` from their feet pulled onto that circle, in place."""
    count, n = points.shape[0], points.shape[1]
    for p in range(count):
        for i in range(n - 2):
            dx, dy = points[p, i + 1, 0] - qx[p, i], points[p, i + 1, 1] - qy[p, i]
            length = np.sqrt(dx * dx + dy * dy)
            scale = limit / max(length, 1e-300) if length > limit else 1.0
            points[p, i + 1, 0], points[p, i + 1, 1] = qx[p, i] + dx * scale, qy[p, i] + dy * scale


@njit(cache=True)
def certified(points, s_inner, near, total, j_arc, jx, jy, distinct, tol2):  # pragma: no cover - compiled
    """Conditions 2-3 of the matching (condition 1 is ``near``) for candidates (P, n, 2) whose feet have
    arc parameters ``s_inner`` (P, n - 2); boolean (P,)."""
    count, n = points.shape[0], points.shape[1]
    width = j_arc.shape[1]
    out = np.zeros(count, dtype=np.bool_)
    for p in range(count):
        ok = near[p]
        previous = 0.0
        for i in range(n - 2):  # the feet run forward along the path, ends included
            if not s_inner[p, i] >= previous:
                ok = False
                break
            previous = s_inner[p, i]
        if ok and not total >= previous:
            ok = False
        i = 0
        while ok and i < n - 1:
            low = 0.0 if i == 0 else s_inner[p, i - 1]
            high = total if i == n - 2 else s_inner[p, i]
            ax, ay = points[p, i, 0], points[p, i, 1]
            ux, uy = points[p, i + 1, 0] - ax, points[p, i + 1, 1] - ay
            length2 = ux * ux + uy * uy
            running = -np.inf
            for c in range(width):
                if not (j_arc[i, c] > low and j_arc[i, c] < high and distinct[i, c]):
                    continue
                vx, vy = jx[i, c] - ax, jy[i, c] - ay
                t = (vx * ux + vy * uy) / (length2 if length2 > 0 else 1.0)
                t = min(max(t, 0.0), 1.0)
                # the vertex within the tolerance of the new segment, its foot not running backwards
                if not (vx - t * ux) ** 2 + (vy - t * uy) ** 2 <= tol2 or t < running:
                    ok = False
                    break
                running = max(running, t)
            i += 1
        out[p] = ok
    return out
