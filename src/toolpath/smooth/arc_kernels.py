"""Compiled loops of the arc screen (numba, the ``fast`` extra): :func:`toolpath.smooth.arc_search._bound`'s
bound of every candidate arc, one candidate at a time, with the NumPy path's arithmetic in its order, and
without its (candidates x points) temporaries (some twenty arrays of a batch's size each)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_TWO_PI = 2.0 * math.pi


@njit(cache=True)
def spiral_bounds(p, o, rows, c, cw, written_end, j, budget):  # pragma: no cover - compiled
    """Per candidate ``n``: the bound of the arc about ``c[n]`` (written ``cw[n]``) from local 0 to
    ``written_end[n]``, over the points ``p[rows[n], :j[n] + 1]`` it was fitted to and the original's
    ``o[rows[n], :j[n] + 1]`` (all local to the start); inf where the vertices do not turn one way inside the
    arc's span.  A candidate stops at its first vertex or segment past ``budget`` (it cannot fit: the figure
    returned is then only some value above the budget)."""
    out = np.empty(len(j))
    for n in range(len(j)):
        b, last = rows[n], j[n]
        cx, cy = cw[n, 0], cw[n, 1]
        sx, sy = -cx, -cy
        ex, ey = written_end[n, 0] - cx, written_end[n, 1] - cy
        # the first segment's turn about the exact centre gives the sense every step must share
        pax, pay = p[b, 0, 0] - c[n, 0], p[b, 0, 1] - c[n, 1]
        pbx, pby = p[b, 1, 0] - c[n, 0], p[b, 1, 1] - c[n, 1]
        sign = np.sign(pax * pby - pay * pbx)
        off0x, off0y = o[b, 0, 0] - cx, o[b, 0, 1] - cy
        lead = math.atan2(sx * off0y - sy * off0x, sx * off0x + sy * off0y) * sign
        sweep = np.mod(math.atan2(sx * ey - sy * ex, sx * ex + sy * ey) * sign, _TWO_PI)
        if sweep <= 0.0:
            sweep = _TWO_PI
        r0, r1 = np.hypot(sx, sy), np.hypot(ex, ey)
        one_way = True
        theta = 0.0
        worst = -np.inf
        ax, ay = off0x, off0y
        d_a = np.hypot(ax, ay)
        frac_a = min(max((lead + theta) / sweep, 0.0), 1.0)
        r_a = r0 + (r1 - r0) * frac_a
        worst = max(worst, abs(d_a - r_a))
        for k in range(last):
            bx, by = o[b, k + 1, 0] - cx, o[b, k + 1, 1] - cy
            ux, uy = bx - ax, by - ay
            cross = ax * uy - ay * ux
            dot = ax * bx + ay * by
            pax, pay = p[b, k, 0] - c[n, 0], p[b, k, 1] - c[n, 1]
            pbx, pby = p[b, k + 1, 0] - c[n, 0], p[b, k + 1, 1] - c[n, 1]
            turn = pax * pby - pay * pbx
            if not (turn * sign > 0 and cross * sign > 0 and dot > 0 and pax * pbx + pay * pby > 0):
                one_way = False
                break
            theta += math.atan2(cross, dot) * sign
            frac = (lead + theta) / sweep
            if k + 1 < last and (frac < 0.0 or frac > 1.0):  # an interior vertex off the span: no bound
                one_way = False
                break
            frac = min(max(frac, 0.0), 1.0)
            r_b = r0 + (r1 - r0) * frac
            d_b = np.hypot(bx, by)
            t = min(max(-(ax * ux + ay * uy) / max(ux * ux + uy * uy, 1e-300), 0.0), 1.0)
            nearest = np.hypot(ax + t * ux, ay + t * uy)
            inside = max(r_a, r_b) - nearest
            outside = max(d_a, d_b) - min(r_a, r_b)
            worst = max(worst, abs(d_b - r_b), max(inside, outside))
            if worst > budget:
                break
            ax, ay, d_a, r_a = bx, by, d_b, r_b
        if one_way and not theta < _TWO_PI - 1e-9:  # the turn from the first vertex to the last
            one_way = False
        if not one_way:
            out[n] = np.inf
            continue
        if worst > budget:
            out[n] = worst
            continue
        out[n] = max(worst, np.hypot(ax - ex, ay - ey))  # the last vertex against the end as written
    return out
