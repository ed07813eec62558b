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


@njit(cache=True)
def _worst_miss(p, jj, t, half, nx, ny, cx, cy):  # pragma: no cover - compiled
    """The largest radial miss of the points between the ends for the centre at ``t`` on the bisector (the
    ``worst`` of :func:`toolpath.smooth.arc_search._golden`)."""
    radius2 = half * half + t * t
    root = math.sqrt(radius2)
    worst = 0.0
    for k in range(1, jj):
        px, py = p[k, 0], p[k, 1]
        a = 2.0 * (px * nx + py * ny)
        miss = (px * px + py * py) - (px * cx + py * cy)
        worst = max(worst, abs(math.sqrt(max(radius2 + miss - t * a, 0.0)) - root))
    return worst


@njit(cache=True)
def screen(xy, original, target, decimals, end_scale, centre_scale, starts, j, valid, end, budget,
           min_segments, max_radius, grid, golden, golden_steps):  # pragma: no cover - compiled
    """:func:`toolpath.smooth.arc_search._measure_ends` one candidate at a time: per start ``b`` and end
    ``starts[b] + j[b, m]`` where ``valid``, whether an arc fits (least squares centre, else the minimax one,
    else the flattest allowed, each measured by :func:`spiral_bounds`'s rule) and its centre, local to the
    start (the caller adds the start)."""
    count, width = j.shape
    n = xy.shape[0]
    fits = np.zeros((count, width), np.bool_)
    centre = np.zeros((count, width, 2))
    size = 0
    for b in range(count):
        for m in range(width):
            size = max(size, j[b, m])
    p = np.empty((1, size + 1, 2))
    o = np.empty((1, size + 1, 2))
    rows = np.zeros(1, np.int64)
    c = np.empty((1, 2))
    cw = np.empty((1, 2))
    written_end = np.empty((1, 2))
    jj_one = np.empty(1, np.int64)
    for b in range(count):
        s = starts[b]
        for m in range(width):
            jj = j[b, m]
            if not valid[b, m] or jj < min_segments or s + jj > end:
                continue
            for k in range(jj + 1):
                q = min(s + k, n - 1)
                p[0, k, 0], p[0, k, 1] = xy[q, 0] - xy[s, 0], xy[q, 1] - xy[s, 1]
                o[0, k, 0], o[0, k, 1] = original[q, 0] - xy[s, 0], original[q, 1] - xy[s, 1]
            chx, chy = p[0, jj, 0], p[0, jj, 1]
            length = np.hypot(chx, chy)
            if not length > 0:
                continue
            nx, ny = -chy / max(length, 1e-300), chx / max(length, 1e-300)
            top, bottom, side = 0.0, 0.0, 0.0
            for k in range(1, jj):
                px, py = p[0, k, 0], p[0, k, 1]
                along = px * nx + py * ny
                a = 2.0 * along
                miss = (px * px + py * py) - (px * chx + py * chy)
                top += a * miss
                bottom += a * a
                side += along
            least = top / max(bottom, 1e-300)
            half = length / 2.0
            qi = min(s + jj, n - 1)
            power = 10.0 ** decimals[qi]
            for kind in range(3):
                if kind == 0:
                    t = least
                elif kind == 1:
                    t = _golden(p[0], jj, least, half, nx, ny, chx, chy, grid, golden, golden_steps)
                else:
                    reach = math.sqrt(max((max_radius * (1.0 - 1e-9)) ** 2 - half * half, 0.0))
                    t = -np.sign(side) * reach
                c[0, 0], c[0, 1] = chx / 2.0 + t * nx, chy / 2.0 + t * ny
                for d in range(2):
                    cw[0, d] = np.rint(c[0, d] / centre_scale[s] * power) / power * centre_scale[s]
                    written_end[0, d] = p[0, jj, d] + (np.rint(target[qi, d] * power) / power
                                                       - target[qi, d]) * end_scale[qi]
                jj_one[0] = jj
                bound = spiral_bounds(p, o, rows, c, cw, written_end, jj_one, budget)[0]
                if bound <= budget and np.hypot(c[0, 0], c[0, 1]) <= max_radius and np.isfinite(bound):
                    fits[b, m] = True
                    centre[b, m, 0], centre[b, m, 1] = c[0, 0], c[0, 1]
                    break
    return fits, centre


@njit(cache=True)
def _golden(p, jj, least, half, nx, ny, cx, cy, grid, golden, steps):  # pragma: no cover - compiled
    """:func:`toolpath.smooth.arc_search._golden` for one candidate: a coarse grid within 5 % of the chord
    around ``least``, then golden section in its best cell."""
    width = 0.05 * (abs(least) + 2.0 * half)
    best, at = np.inf, 0
    for g in range(grid.shape[0]):
        value = _worst_miss(p, jj, least + grid[g] * width, half, nx, ny, cx, cy)
        if value < best:
            best, at = value, g
    middle = least + grid[at] * width
    cell = width * 2.0 / (grid.shape[0] - 1)
    lo, hi = middle - cell, middle + cell
    x1, x2 = hi - golden * (hi - lo), lo + golden * (hi - lo)
    f1 = _worst_miss(p, jj, x1, half, nx, ny, cx, cy)
    f2 = _worst_miss(p, jj, x2, half, nx, ny, cx, cy)
    for _ in range(steps):
        left = f1 < f2
        if left:
            hi = x2
            x2, x1 = x1, hi - golden * (hi - lo)
            f2, f1 = f1, _worst_miss(p, jj, x1, half, nx, ny, cx, cy)
        else:
            lo = x1
            x1, x2 = x2, lo + golden * (hi - lo)
            f1, f2 = f2, _worst_miss(p, jj, x2, half, nx, ny, cx, cy)
    return x1 if f1 < f2 else x2
