"""The exact two-sided (Hausdorff) distance between two polylines, computed on their segments.

A machinist's "within 0.05 mm" is a band both ways: every point of the new path within 0.05 mm of
the old one **and** every point of the old within 0.05 mm of the new.  That is the Hausdorff distance
``max(h(A, B), h(B, A))`` with ``h(A, B) = sup_{a in A} d(a, B)`` over *all* points of the segments,
not only the vertices (a path that cuts a corner has its vertices on the old path and its chord far
from the old corner).

Why the candidates below are exact.  Along a segment ``a(t) = a0 + t u`` of A (t in [0, 1]) the
distance ``d_j(t)`` to a segment j of B is convex (distance to a convex set, composed with an affine
map), so ``f(t) = min_j d_j(t)`` has its local maxima only at ``t = 0, 1`` or where two of the
``d_j`` are equal.  There ``d_j`` is the distance to one *feature* of j (an end point, or its line
where the foot falls inside), and each feature's squared distance is a quadratic in t; so every
such t is a root of the difference of two quadratics.  We evaluate the true ``f`` at all those roots
(extra candidates only add values ``<= h``), and skip pairs of segments that cannot be nearest:
``f(t) <= UB = min_j max(d_j(0), d_j(1))`` on the whole segment, so a segment j farther than UB from
it never attains the minimum.  Identical features (a shared vertex, collinear segments) have no
crossing that can make a maximum and are skipped.
"""

from __future__ import annotations

import importlib.util

import numpy as np

from toolpath.geometry.deviation import point_to_polyline

# (A segments) x (B segments) distances held at once when batching; chunks keep memory bounded
_MASK_BUDGET = 4_000_000
WHOLE_PAIRS = 100_000  # pieced_hausdorff measures polylines with fewer point pairs whole
COMPILED_PIECE = 8  # segments a piece in compiled loops (their cost grows with the stretch a piece needs)


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points ``p`` to segments ``a``-``b``, all broadcast together (..., 2)."""
    # per coordinate: several times faster than einsum / norm over an axis of 2
    abx, aby = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    apx, apy = p[..., 0] - a[..., 0], p[..., 1] - a[..., 1]
    length2 = abx * abx + aby * aby
    t = np.clip((apx * abx + apy * aby) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    dx, dy = apx - t * abx, apy - t * aby
    return np.sqrt(dx * dx + dy * dy)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _segments_intersect(a0, a1, b0, b1) -> np.ndarray:
    """True where segment a0-a1 meets b0-b1 (touching counts), all broadcast (..., 2)."""
    d1 = _cross(b1 - b0, a0 - b0)
    d2 = _cross(b1 - b0, a1 - b0)
    d3 = _cross(a1 - a0, b0 - a0)
    d4 = _cross(a1 - a0, b1 - a0)
    return (d1 * d2 <= 0) & (d3 * d4 <= 0)


def _feature_quadratics(a0: np.ndarray, u: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Squared distance from ``a0 + t u`` to the three features of every B segment, as quadratic
    coefficients: shape (..., nA, mB, 3 features, 3 coefficients) for features (start, end, line)."""
    a0 = a0[..., :, None, :]
    u = u[..., :, None, :]
    start, end = b[..., None, :-1, :], b[..., None, 1:, :]
    out = []
    for p in (start, end):
        w = a0 - p
        out.append(np.stack(np.broadcast_arrays(np.einsum("...k,...k->...", u, u),
                                                2 * np.einsum("...k,...k->...", u, w),
                                                np.einsum("...k,...k->...", w, w)), axis=-1))
    direction = end - start
    length = np.linalg.norm(direction, axis=-1, keepdims=True)
    normal = np.stack([-direction[..., 1], direction[..., 0]], axis=-1) / np.where(length > 0, length, 1.0)
    un = np.einsum("...k,...k->...", u, normal)
    wn = np.einsum("...k,...k->...", a0 - start, normal)
    out.append(np.stack(np.broadcast_arrays(un * un, 2 * un * wn, wn * wn), axis=-1))
    return np.stack(out, axis=-2)


def _roots(q: np.ndarray) -> np.ndarray:
    """Real roots in [0, 1] of ``q[..., 0] t^2 + q[..., 1] t + q[..., 2]``, as (..., 2) with NaN for
    none (a double root, or the vertex of a quadratic with no real root, is returned too: extra
    candidates are harmless, a missed crossing is not)."""
    a, b, c = q[..., 0], q[..., 1], q[..., 2]
    scale = np.maximum(np.maximum(np.abs(a), np.abs(b)), np.abs(c))
    tiny = 1e-13 * np.maximum(scale, 1e-300)
    with np.errstate(divide="ignore", invalid="ignore"):
        disc = b * b - 4 * a * c
        sq = np.sqrt(np.maximum(disc, 0.0))
        # the numerically stable pair of roots
        qq = -0.5 * (b + np.copysign(sq, b))
        r1 = np.where(np.abs(a) > tiny, qq / a, np.where(np.abs(b) > tiny, -c / b, np.nan))
        r2 = np.where((np.abs(a) > tiny) & (np.abs(qq) > tiny), c / qq, r1)
    roots = np.stack([r1, r2], axis=-1)
    roots[scale <= 1e-300] = np.nan  # identical features: no crossing
    return np.where((roots >= 0.0) & (roots <= 1.0), roots, np.nan)


def _pairs_within_rows(near: np.ndarray) -> tuple[np.ndarray, ...]:
    """Every pair (j < k) of True entries within each row of ``near`` (k, n, m), sparsely:
    (batch index, row, j, k)."""
    w, i, j = np.nonzero(near)  # lexicographic: members of a row are contiguous
    row = w * near.shape[1] + i
    starts = np.flatnonzero(np.r_[True, row[1:] != row[:-1]]) if len(row) else np.zeros(0, dtype=int)
    counts = np.diff(np.r_[starts, len(row)])
    position = np.arange(len(row)) - np.repeat(starts, counts)
    partners = np.repeat(counts, counts) - position - 1
    first = np.repeat(np.arange(len(row)), partners)
    second = first + 1 + np.arange(len(first)) - np.repeat(np.cumsum(partners) - partners, partners)
    return w[first], i[first], j[first], j[second]


def _subdivide(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` (k, n, 2) with each segment cut into pieces about as long as ``b``'s typical segment.
    The point set is unchanged (so is h(A, B)); short pieces keep the candidate sets small when a
    long segment runs beside a finely sampled path."""
    length = np.linalg.norm(np.diff(a, axis=1), axis=-1).max(axis=0)  # (n-1,), the longest over the batch
    step = float(np.median(np.linalg.norm(np.diff(b, axis=1), axis=-1)))
    if not step > 0:
        return a
    pieces = np.clip(np.ceil(length / (2 * step)), 1, 256).astype(int)
    if pieces.max() == 1:
        return a
    t = np.concatenate([np.arange(p) / p for p in pieces])  # the start of every piece
    seg = np.repeat(np.arange(len(pieces)), pieces)
    start, end = a[:, seg], a[:, seg + 1]
    return np.concatenate([start + t[None, :, None] * (end - start), a[:, -1:]], axis=1)


def _directed_chunk(a: np.ndarray, b: np.ndarray, subdivide: bool = True) -> np.ndarray:
    """:func:`directed_hausdorff` on a batch (k, n, 2) x (k, m, 2)."""
    best = point_to_polyline(a, b).max(axis=-1)  # the vertices of A (t = 0, 1)
    if a.shape[1] < 2 or b.shape[1] < 2:
        return best
    if subdivide:
        a = _subdivide(a, b)
    a0, a1 = a[:, :-1], a[:, 1:]
    b0, b1 = b[:, :-1], b[:, 1:]
    # d_j at both ends of every A segment, (k, n-1, m-1)
    d0 = _point_segment_distance(a0[:, :, None], b0[:, None], b1[:, None])
    d1 = _point_segment_distance(a1[:, :, None], b0[:, None], b1[:, None])
    upper = np.maximum(d0, d1).min(axis=-1, keepdims=True)
    gap = np.minimum(np.minimum(d0, d1),
                     np.minimum(_point_segment_distance(b0[:, None], a0[:, :, None], a1[:, :, None]),
                                _point_segment_distance(b1[:, None], a0[:, :, None], a1[:, :, None])))
    gap = np.where(_segments_intersect(a0[:, :, None], a1[:, :, None], b0[:, None], b1[:, None]), 0.0, gap)
    # f at every piece's ends is exact already; a piece whose upper bound cannot beat the best of
    # them cannot hold the maximum (after subdivision this drops nearly every piece)
    best = np.maximum(best, np.maximum(d0.min(axis=-1), d1.min(axis=-1)).max(axis=-1))
    useful = upper > best[:, None, None] * (1 + 1e-12)
    w, i, j, jj = _pairs_within_rows((gap <= upper * (1 + 1e-12) + 1e-300) & useful)
    if len(w) == 0:
        return best
    # the three features of segments j and jj, as quadratics in t along A's segment i
    fj = _feature_quadratics(a0[w, i][:, None], (a1 - a0)[w, i][:, None], np.stack([b0[w, j], b1[w, j]], 1))
    fk = _feature_quadratics(a0[w, i][:, None], (a1 - a0)[w, i][:, None], np.stack([b0[w, jj], b1[w, jj]], 1))
    difference = fj[:, 0, 0, :, None, :] - fk[:, 0, 0, None, :, :]  # every feature of j against every one of k
    t = _roots(difference).reshape(len(w), -1)  # (P, 18)
    keep = ~np.isnan(t)
    rows = np.broadcast_to(np.arange(len(w))[:, None], t.shape)[keep]
    tt = t[keep]
    if len(tt) == 0:
        return best
    owner, seg, near_j, near_k = w[rows], i[rows], j[rows], jj[rows]
    points = a0[owner, seg] + tt[:, None] * (a1 - a0)[owner, seg]
    # a crossing of the two *segment* distances is a candidate; roots of features that are not the
    # nearest part of their segment there are not (keeping a few extra ones is harmless)
    dj = _point_segment_distance(points, b0[owner, near_j], b1[owner, near_j])
    dk = _point_segment_distance(points, b0[owner, near_k], b1[owner, near_k])
    real = (np.abs(dj - dk) <= 1e-9 * (1.0 + dj)) & (dj <= upper[owner, seg, 0] * (1 + 1e-9) + 1e-12)
    owner, points = owner[real], points[real]
    if len(owner) == 0:
        return best
    dist = _point_segment_distance(points[:, None], b0[owner], b1[owner]).min(axis=-1)
    np.maximum.at(best, owner, dist)
    return best


def directed_hausdorff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``h(A, B)``: the farthest point of polyline ``a`` (any point of its segments) from polyline ``b``.

    ``a`` (..., n, 2) and ``b`` (..., m, 2) with broadcastable batch shapes; returns (...,).  Exact up to
    floating-point rounding (see the module docstring).  Cost O(n m) per pair plus the few crossings of
    nearby segments; meant for windows and corners, not for whole programs at once.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    batch = np.broadcast_shapes(a.shape[:-2], b.shape[:-2])
    a = np.broadcast_to(a, (*batch, *a.shape[-2:])).reshape(-1, *a.shape[-2:])
    b = np.broadcast_to(b, (*batch, *b.shape[-2:])).reshape(-1, *b.shape[-2:])
    per_item = max(1, 8 * a.shape[1] * b.shape[1])
    step = max(1, _MASK_BUDGET // per_item)
    out = np.concatenate([_directed_chunk(a[s:s + step], b[s:s + step]) for s in range(0, len(a), step)]) \
        if len(a) else np.zeros(0)
    return out.reshape(batch)


def hausdorff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The two-sided distance ``max(h(A, B), h(B, A))`` between polylines, exact on segments; (...,)."""
    return np.maximum(directed_hausdorff(a, b), directed_hausdorff(b, a))


def pieced_hausdorff(a: np.ndarray, b: np.ndarray, piece: int = 32, compiled: bool = False) -> float:
    """:func:`hausdorff` of two single polylines (n, 2) and (m, 2), exact, for long ones that run near each
    other (an arc read as fine chords and the lines it replaced): each direction in pieces of ``piece``
    segments, each against the stretch of the other that can hold its nearest points.  In compiled loops
    (numba, the ``fast`` extra, where installed) when the pair is long or ``compiled`` asks for them (a caller
    with many pairs to measure: numba's import is paid once).

    Why the stretch is enough.  Along a segment of length ``L`` the distance to the other polyline is
    1-Lipschitz, so it never exceeds ``(f0 + f1 + L) / 2`` (``f`` at the segment's ends); a segment of the
    other polyline nearest to some point of the piece lies within the largest such bound of that point,
    hence meets the piece's bounding box grown by it.  The stretch runs from the first to the last segment
    that does, so it holds every segment that can be nearest."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    whole = len(a) * len(b) <= WHOLE_PAIRS
    kernels = compiled_kernels() if compiled or not whole else None
    if kernels is not None and len(a) >= 2 and len(b) >= 2:  # the same candidates in compiled loops
        a, b = np.ascontiguousarray(a[:, :2]), np.ascontiguousarray(b[:, :2])
        piece = min(piece, COMPILED_PIECE)
        return max(float(kernels.directed_pieced(a, b, piece)), float(kernels.directed_pieced(b, a, piece)))
    if whole:
        return float(hausdorff(a, b))
    return max(_directed_pieced(a, b, piece), _directed_pieced(b, a, piece))


def compiled_kernels():
    """:mod:`toolpath.geometry.hausdorff_kernels` when numba is installed (the ``fast`` extra), else None:
    the NumPy functions here measure the same, more slowly."""
    if importlib.util.find_spec("numba") is None:  # only numba's absence falls back: a broken kernel module fails
        return None
    from toolpath.geometry import hausdorff_kernels

    return hausdorff_kernels


def _directed_pieced(a: np.ndarray, b: np.ndarray, piece: int) -> float:
    if len(a) < 2 or len(b) < 2:
        return float(directed_hausdorff(a, b))
    low_b, high_b = np.minimum(b[:-1], b[1:]), np.maximum(b[:-1], b[1:])
    worst = 0.0
    reach = float(point_to_polyline(a[:1], b)[0])  # the first point's distance, exact
    for start in range(0, len(a) - 1, piece):
        part = a[start:start + piece + 1]
        # the piece's distances bounded from above by the stretch of B near it (a part of B only over-states
        # a distance, so the stretch found from these bounds still holds every nearest segment); the last
        # piece's reach covers this piece's first point, so the stretch is never empty
        low, high = part.min(axis=0) - reach, part.max(axis=0) + reach
        near = np.flatnonzero(np.all((low_b <= high) & (high_b >= low), axis=1))
        ends = point_to_polyline(part, b[near[0]:near[-1] + 2] if len(near) else b)
        reach = float(((ends[:-1] + ends[1:] + np.hypot(*np.diff(part, axis=0).T)) / 2.0).max())
        low, high = part.min(axis=0) - reach, part.max(axis=0) + reach
        near = np.flatnonzero(np.all((low_b <= high) & (high_b >= low), axis=1))
        stretch = b[near[0]:near[-1] + 2] if len(near) else b
        worst = max(worst, float(directed_hausdorff(part, stretch)))
    return worst


def moved_hausdorff(old: list[np.ndarray], new: list[np.ndarray], band: int = 2) -> np.ndarray:
    """:func:`hausdorff` of each polyline ``old[k]`` (n, 2) and the same polyline with its points moved,
    ``new[k]`` (``new[k][i]`` is ``old[k][i]`` moved), in O(n) instead of O(n^2) per pair; (len(old),).

    Why a band of segments is exact.  On segment i of one polyline, the distance to the other is at most
    ``U_i``, the larger move of the segment's two end points (the points ``(1 - t) p + t q`` of the two
    segments i are that close, by convexity).  A segment j of the other polyline that is farther than
    ``U_i`` from segment i is never the nearest, so only segments within ``band`` places of i are used
    wherever every segment farther in index is shown farther in space: ``|m_i - m_j| > h_i + h_j + U``
    (mid-points ``m``, half-lengths ``h``).  A pair where that test fails (a path folding back within a
    few moves of itself) is measured by :func:`hausdorff` whole.
    """
    window = 2 * band + 2  # points of the band around a segment
    result = np.zeros(len(old))
    sizes = np.array([len(a) for a in old], int)
    if any(a.shape != b.shape for a, b in zip(old, new, strict=True)):
        raise ValueError("every polyline must keep its number of points when moved")
    banded = []
    for size in np.unique(sizes):  # polylines of one length are checked, or measured whole, in one batch
        group = np.flatnonzero(sizes == size)
        a, b = np.stack([old[k] for k in group]), np.stack([new[k] for k in group])
        far = _far_out_of_band(a, b, band) if size >= window else np.zeros(len(group), bool)
        banded.extend(group[far].tolist())
        if not far.all():
            result[group[~far]] = hausdorff(a[~far], b[~far])
    if banded:
        result[banded] = _banded(old, new, banded, band, window)
    return result


def _far_out_of_band(a: np.ndarray, b: np.ndarray, band: int) -> np.ndarray:
    """Per polyline pair (k, n, 2): True when every segment farther than ``band`` places is far in space."""
    if len(a) > 256:  # the (k, n, n) arrays below stay a few tens of MB
        return np.concatenate([_far_out_of_band(a[s:s + 256], b[s:s + 256], band) for s in range(0, len(a), 256)])
    move = np.linalg.norm(a - b, axis=-1)
    reach = np.maximum(move[:, :-1], move[:, 1:])  # U_i, on both polylines' segment i
    mid_a, mid_b = (a[:, :-1] + a[:, 1:]) / 2, (b[:, :-1] + b[:, 1:]) / 2
    half_a = np.linalg.norm(np.diff(a, axis=1), axis=-1) / 2
    half_b = np.linalg.norm(np.diff(b, axis=1), axis=-1) / 2
    dx = mid_a[:, :, None, 0] - mid_b[:, None, :, 0]
    dy = mid_a[:, :, None, 1] - mid_b[:, None, :, 1]
    needed = half_a[:, :, None] + half_b[:, None, :] + np.maximum(reach[:, :, None], reach[:, None, :])
    needed = needed * (1 + 1e-9) + 1e-12
    index = np.arange(reach.shape[1])
    in_band = np.abs(index[:, None] - index[None]) <= band
    return np.all((dx * dx + dy * dy > needed * needed) | in_band, axis=(1, 2))


def _banded(old, new, which: list[int], band: int, window: int) -> np.ndarray:
    sizes = np.array([len(old[k]) for k in which])
    offsets = np.r_[0, np.cumsum(sizes)[:-1]]
    a_all, b_all = np.concatenate([old[k] for k in which]), np.concatenate([new[k] for k in which])
    segments = sizes - 1
    firsts = np.r_[0, np.cumsum(segments)[:-1]]
    owner = np.repeat(np.arange(len(which)), segments)
    local = np.arange(segments.sum()) - np.repeat(firsts, segments)
    first = offsets[owner] + local  # each segment's first point, globally
    start = offsets[owner] + np.clip(local - band, 0, sizes[owner] - window)  # its band's first point
    pair, span = first[:, None] + np.arange(2), start[:, None] + np.arange(window)
    directions = [(a_all[pair], b_all[span]), (b_all[pair], a_all[span])]
    # every segment's end points against its band: the vertices' distances, and the bound on the
    # segment's inside (min over j of max(d_j(0), d_j(1))) that lets most segments be skipped
    vertex, upper = [], []
    for ends, near in directions:
        d = _point_segment_distance(ends[:, :, None], near[:, None, :-1], near[:, None, 1:])  # (K, 2, window - 1)
        vertex.append(d.min(axis=-1).max(axis=-1))
        upper.append(d.max(axis=1).min(axis=-1))
    worst = np.maximum.reduceat(np.maximum(*vertex), firsts)  # the farthest vertex, per polyline
    step = 20_000  # segments per batch: memory stays a few tens of MB
    for (ends, near), bound in zip(directions, upper, strict=True):
        inside = np.flatnonzero(bound > worst[owner] * (1 + 1e-12))
        for s in range(0, len(inside), step):
            pick = inside[s:s + step]
            np.maximum.at(worst, owner[pick], _directed_chunk(ends[pick], near[pick], subdivide=False))
    return worst
