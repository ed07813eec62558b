"""Compiled loops of :func:`toolpath.geometry.hausdorff.pieced_hausdorff` (numba): the same exact measure,
one segment at a time instead of (segments x segments) NumPy temporaries.

The candidates are those of :mod:`toolpath.geometry.hausdorff` (its docstring says why they are exact): along
a segment of A, the ends, and every root in [0, 1] of the difference of two feature quadratics (end point or
line of two segments of B that can be nearest there); ``f`` is evaluated at each.  A segment of B farther
from the A segment than ``UB = min_j max(d_j(0), d_j(1))`` is never nearest on it, so ``f`` at a root is the
least distance over the segments within ``UB`` alone.  numba is an optional extra (``toolpath-lab[fast]``);
without it the NumPy functions measure the same.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_SLACK = 1e-12  # relative: a bound compared with a measured distance, as the NumPy path compares them
_GROUP = 32  # segments of B per bounding box when looking for a piece's stretch
_RUN = 8  # longest run of B between the segments nearest to an A segment's ends that is bounded on its own


@njit(cache=True)
def _segment_distance(px, py, ax, ay, bx, by):  # pragma: no cover - compiled
    abx, aby = bx - ax, by - ay
    apx, apy = px - ax, py - ay
    length2 = abx * abx + aby * aby
    t = (apx * abx + apy * aby) / length2 if length2 > 0.0 else 0.0
    t = min(max(t, 0.0), 1.0)
    dx, dy = apx - t * abx, apy - t * aby
    return math.sqrt(dx * dx + dy * dy)


@njit(cache=True)
def _to_segments(px, py, b, lo, hi):  # pragma: no cover - compiled
    """Distance from (px, py) to the segments ``lo .. hi - 1`` of ``b`` (segment j runs b[j] -> b[j + 1])."""
    return _nearest(px, py, b, lo, hi)[0]


@njit(cache=True)
def _nearest(px, py, b, lo, hi):  # pragma: no cover - compiled
    """:func:`_to_segments` and the first segment at that distance."""
    best, at = np.inf, lo
    for j in range(lo, hi):
        d = _segment_distance(px, py, b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1])
        if d < best:
            best, at = d, j
    return best, at


@njit(cache=True)
def _cross(ux, uy, vx, vy):  # pragma: no cover - compiled
    return ux * vy - uy * vx


@njit(cache=True)
def _intersect(a0x, a0y, a1x, a1y, b0x, b0y, b1x, b1y):  # pragma: no cover - compiled
    d1 = _cross(b1x - b0x, b1y - b0y, a0x - b0x, a0y - b0y)
    d2 = _cross(b1x - b0x, b1y - b0y, a1x - b0x, a1y - b0y)
    d3 = _cross(a1x - a0x, a1y - a0y, b0x - a0x, b0y - a0y)
    d4 = _cross(a1x - a0x, a1y - a0y, b1x - a0x, b1y - a0y)
    return d1 * d2 <= 0.0 and d3 * d4 <= 0.0


@njit(cache=True)
def _quadratic(a0x, a0y, ux, uy, feature, sx, sy, ex, ey, out):  # pragma: no cover - compiled
    """Squared distance from ``a0 + t u`` to a feature of segment s -> e (0 its start, 1 its end, 2 its
    line) as the coefficients of ``t^2, t, 1`` in ``out``."""
    if feature < 2:
        px, py = (sx, sy) if feature == 0 else (ex, ey)
        wx, wy = a0x - px, a0y - py
        out[0], out[1], out[2] = ux * ux + uy * uy, 2.0 * (ux * wx + uy * wy), wx * wx + wy * wy
        return
    dx, dy = ex - sx, ey - sy
    length = math.sqrt(dx * dx + dy * dy)
    if length <= 0.0:
        length = 1.0
    nx, ny = -dy / length, dx / length
    un = ux * nx + uy * ny
    wn = (a0x - sx) * nx + (a0y - sy) * ny
    out[0], out[1], out[2] = un * un, 2.0 * un * wn, wn * wn


@njit(cache=True)
def _roots(a, b, c, out):  # pragma: no cover - compiled
    """Real roots in [0, 1] of ``a t^2 + b t + c`` into ``out``; how many (the vertex of a quadratic with
    no real root is returned too, as by :func:`toolpath.geometry.hausdorff._roots`)."""
    scale = max(abs(a), abs(b), abs(c))
    if scale <= 1e-300:  # identical features: no crossing
        return 0
    tiny = 1e-13 * scale
    sq = math.sqrt(max(b * b - 4.0 * a * c, 0.0))
    qq = -0.5 * (b + math.copysign(sq, b))
    if abs(a) > tiny:
        r1 = qq / a
    elif abs(b) > tiny:
        r1 = -c / b
    else:
        return 0
    r2 = c / qq if (abs(a) > tiny and abs(qq) > tiny) else r1
    count = 0
    for r in (r1, r2):
        if 0.0 <= r <= 1.0:
            out[count] = r
            count += 1
    return count


@njit(cache=True)
def _directed_piece(a, start, stop, b, lo, hi, best, at):  # pragma: no cover - compiled
    """``max(best, h(A', B'))`` for the segments ``start .. stop - 1`` of ``a`` and the segments ``lo .. hi - 1``
    of ``b`` (a stretch holding every segment that can be nearest to a point of the piece), ``best`` at least
    the largest distance of the piece's points; ``at[p]``: a segment of B nearest to point p of A."""
    near = np.empty(max(hi - lo, _RUN), np.int64)  # a run below may lie partly outside the stretch
    larger = np.empty(max(hi - lo, _RUN))  # per segment in ``near``: its larger distance at the A segment's ends
    ends = np.empty((hi - lo, 2))  # per segment of the stretch: its distances at the A segment's ends
    qj, qk, roots = np.empty(3), np.empty(3), np.empty(2)
    for i in range(start, stop):
        a0x, a0y, a1x, a1y = a[i, 0], a[i, 1], a[i + 1, 0], a[i + 1, 1]
        # UB over the two segments nearest to the ends first (a bound of UB): most segments stop here
        upper = np.inf
        for j in (at[i], at[i + 1]):
            d0 = _segment_distance(a0x, a0y, b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1])
            d1 = _segment_distance(a1x, a1y, b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1])
            upper = min(upper, max(d0, d1))
        if not upper > best * (1.0 + _SLACK):
            continue
        # then the exact maximum of the distance to the run of B from one end's nearest segment to the other's
        # alone (f is at most that): a segment longer than B's runs past a few of them, and their crossings
        # decide it without the whole stretch
        first, last = min(at[i], at[i + 1]), max(at[i], at[i + 1])
        if last - first < _RUN:
            count = 0
            for j in range(first, last + 1):
                d0 = _segment_distance(a0x, a0y, b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1])
                d1 = _segment_distance(a1x, a1y, b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1])
                near[count], larger[count] = j, max(d0, d1)
                count += 1
            if not _crossings(a0x, a0y, a1x, a1y, b, near, larger, count, best, qj, qk, roots) > \
                    best * (1.0 + _SLACK):
                continue
        for j in range(lo, hi):
            d0 = _segment_distance(a0x, a0y, b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1])
            d1 = _segment_distance(a1x, a1y, b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1])
            ends[j - lo, 0], ends[j - lo, 1] = d0, d1
            upper = min(upper, max(d0, d1))
        if not upper > best * (1.0 + _SLACK):
            continue  # f <= upper on the whole segment: it cannot hold a larger maximum
        count = 0
        for j in range(lo, hi):
            b0x, b0y, b1x, b1y = b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1]
            d0, d1 = ends[j - lo, 0], ends[j - lo, 1]
            if _intersect(a0x, a0y, a1x, a1y, b0x, b0y, b1x, b1y):
                gap = 0.0
            else:
                gap = min(d0, d1, _segment_distance(b0x, b0y, a0x, a0y, a1x, a1y),
                          _segment_distance(b1x, b1y, a0x, a0y, a1x, a1y))
            if gap <= upper * (1.0 + _SLACK) + 1e-300:
                near[count], larger[count] = j, max(d0, d1)
                count += 1
        best = _crossings(a0x, a0y, a1x, a1y, b, near, larger, count, best, qj, qk, roots)
    return best


@njit(cache=True)
def _crossings(a0x, a0y, a1x, a1y, b, near, larger, count, best, qj, qk, roots):  # pragma: no cover - compiled
    """``max(best, f)`` over the crossings along a0 -> a1 of the distances to the segments ``near[:count]`` of
    ``b`` (``f`` the least of them; ``larger``: each one's larger distance at the segment's ends), skipping what
    cannot exceed ``best``: the exact maximum of ``f`` wherever it exceeds ``best``."""
    ux, uy = a1x - a0x, a1y - a0y
    for x in range(count):
        j = near[x]
        for y in range(x + 1, count):
            k = near[y]
            if not min(larger[x], larger[y]) > best:
                continue  # min(d_j, d_k) is at most either's larger end (convex): never above the best
            for fj in range(3):
                _quadratic(a0x, a0y, ux, uy, fj, b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1], qj)
                for fk in range(3):
                    _quadratic(a0x, a0y, ux, uy, fk, b[k, 0], b[k, 1], b[k + 1, 0], b[k + 1, 1], qk)
                    for r in range(_roots(qj[0] - qk[0], qj[1] - qk[1], qj[2] - qk[2], roots)):
                        px, py = a0x + roots[r] * ux, a0y + roots[r] * uy
                        # f there is at most d_j: no larger maximum unless d_j is above the best; and a
                        # root is a crossing of the two segments' distances only where they are equal
                        dj = _segment_distance(px, py, b[j, 0], b[j, 1], b[j + 1, 0], b[j + 1, 1])
                        if not dj > best:
                            continue
                        dk = _segment_distance(px, py, b[k, 0], b[k, 1], b[k + 1, 0], b[k + 1, 1])
                        if abs(dj - dk) > 1e-9 * (1.0 + dj):
                            continue
                        f = np.inf
                        for z in range(count):
                            w = near[z]
                            f = min(f, _segment_distance(px, py, b[w, 0], b[w, 1], b[w + 1, 0], b[w + 1, 1]))
                        best = max(best, f)
    return best


@njit(cache=True)
def _boxes(b, size):  # pragma: no cover - compiled
    """The bounding box (low x, low y, high x, high y) of every ``size`` consecutive segments of ``b``."""
    count = (b.shape[0] - 2) // size + 1
    out = np.empty((count, 4))
    for k in range(count):
        lo, hi = k * size, min((k + 1) * size, b.shape[0] - 1)  # segments lo .. hi - 1: points lo .. hi
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = np.inf, np.inf, -np.inf, -np.inf
        for p in range(lo, hi + 1):
            out[k, 0], out[k, 1] = min(out[k, 0], b[p, 0]), min(out[k, 1], b[p, 1])
            out[k, 2], out[k, 3] = max(out[k, 2], b[p, 0]), max(out[k, 3], b[p, 1])
    return out


@njit(cache=True)
def _stretch(b, boxes, size, low_x, low_y, high_x, high_y):  # pragma: no cover - compiled
    """The first and one past the last segment of ``b`` whose bounding box meets the box; the whole of
    ``b`` when none does.  Groups of ``size`` segments whose ``boxes`` miss it are passed over whole."""
    first, last = -1, -1
    for k in range(boxes.shape[0]):
        if boxes[k, 0] > high_x or boxes[k, 2] < low_x or boxes[k, 1] > high_y or boxes[k, 3] < low_y:
            continue
        for j in range(k * size, min((k + 1) * size, b.shape[0] - 1)):
            if (min(b[j, 0], b[j + 1, 0]) <= high_x and max(b[j, 0], b[j + 1, 0]) >= low_x
                    and min(b[j, 1], b[j + 1, 1]) <= high_y and max(b[j, 1], b[j + 1, 1]) >= low_y):
                if first < 0:
                    first = j
                last = j
    if first < 0:
        return 0, b.shape[0] - 1
    return first, last + 1


@njit(cache=True)
def directed_pieced(a, b, piece):  # pragma: no cover - compiled
    """``h(A, B)`` for polylines ``a`` (n >= 2, 2) and ``b`` (m >= 2, 2), in pieces of ``piece`` segments of A,
    each against the stretch of B that can hold its nearest points (as
    :func:`toolpath.geometry.hausdorff._directed_pieced`, whose docstring says why the stretch is enough)."""
    worst = 0.0
    reach = _to_segments(a[0, 0], a[0, 1], b, 0, b.shape[0] - 1)  # the first point's distance, exact
    pieces = (a.shape[0] - 2) // piece + 1
    stretches = np.empty((pieces, 2), np.int64)
    boxes = _boxes(b, _GROUP)
    at = np.empty(a.shape[0], np.int64)
    # first every piece's stretch and the distances of its points (exact): the largest of them lets the
    # segments' bounds skip nearly every segment below
    for number in range(pieces):
        start = number * piece
        stop = min(start + piece, a.shape[0] - 1)
        low_x, low_y, high_x, high_y = np.inf, np.inf, -np.inf, -np.inf
        for p in range(start, stop + 1):
            low_x, low_y = min(low_x, a[p, 0]), min(low_y, a[p, 1])
            high_x, high_y = max(high_x, a[p, 0]), max(high_y, a[p, 1])
        # distances at the piece's points bounded from above by a stretch of B near it, then the piece's
        # reach (a distance along a segment never exceeds (f0 + f1 + L) / 2: 1-Lipschitz)
        lo, hi = _stretch(b, boxes, _GROUP, low_x - reach, low_y - reach, high_x + reach, high_y + reach)
        previous = _to_segments(a[start, 0], a[start, 1], b, lo, hi)
        reach = 0.0
        for p in range(start + 1, stop + 1):
            here = _to_segments(a[p, 0], a[p, 1], b, lo, hi)
            length = math.hypot(a[p, 0] - a[p - 1, 0], a[p, 1] - a[p - 1, 1])
            reach = max(reach, (previous + here + length) / 2.0)
            previous = here
        lo, hi = _stretch(b, boxes, _GROUP, low_x - reach, low_y - reach, high_x + reach, high_y + reach)
        stretches[number, 0], stretches[number, 1] = lo, hi
        for p in range(start, stop + 1):
            distance, at[p] = _nearest(a[p, 0], a[p, 1], b, lo, hi)
            worst = max(worst, distance)
    for number in range(pieces):
        start = number * piece
        stop = min(start + piece, a.shape[0] - 1)
        worst = _directed_piece(a, start, stop, b, stretches[number, 0], stretches[number, 1], worst, at)
    return worst
