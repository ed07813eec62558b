"""Which arcs a chain of G1 points allows, found for many starts and ends at once (issue 44: ``--arcs``
uses the whole band and writes the fewest lines).

For a start ``i`` and every end ``q = i + j`` within a block of ``K`` points, up to three arcs through both
ends are tried in turn, each only where the ones before do not fit: the centre on the chord's bisector
nearest (least squares, algebraically) to the points between, the one whose largest radial miss of those
points is least (a golden-section search along the bisector), and the flattest allowed (for a straight run
in noisy steps, whose algebraic centre is unstable).  Each is measured as
:func:`toolpath.smooth.arc_weld.spiral_bound` measures one arc: with
its end point and centre rounded as they are written, the reader's spiral between the two radii, every
original vertex and segment paired with the arc along rays from the centre.  The arrays are
``(starts, ends, points)``; a start measures its ends in windows, each twice as long as the one before,
while arcs fit near a window's last end.  The fewest blocks then follow by dynamic programming over the
ends (:func:`fewest_blocks`), which measures a start only at the ends whose count it could lower and,
inside a long arc, only the last starts before its end (a later start reaches about as far).  Everything
here is a screen: the arcs chosen are measured again one by one with the numbers as formatted, and the
output is re-read and measured exactly by the caller.
"""

from __future__ import annotations

import importlib.util
import math
from dataclasses import dataclass

import numpy as np

FIRST_WINDOW = 16      # ends a start measures at first (the window doubles while arcs fit near its end)
LAST_WINDOW = 256      # the longest window (NumPy: a batch holds some twenty (ends x points) arrays)
COMPILED_LAST_WINDOW = 1024  # ... where the screen runs in compiled loops, one candidate at a time (no such
                             # arrays): fewer windows a long arc (the time: make bench, reports/bench/arcs.json)
GALLOP = 64            # from windows this long on, a window's last end(s) are measured first: where an arc fits
                       # there, its other ends are taken to fit (the arcs chosen are measured again one by one)
SKIP_GAP = 8           # a start is measured unless a point this far on (or up to twice) has no more blocks
CELLS = 1 << 18        # ends x points per batch: about 2 MB an array
COMPILED_CELLS = 1 << 16  # candidates x points from which a batch's bounds run in compiled loops (numba)
STARTS_PER_STEP = 8    # starts measured between updates of the counts: more share numpy's overhead, fewer
                       # measure fewer ends inside a long arc (each measures only past the last count)
IDLE_WINDOW = 1024     # starts looked at at once for chunks that would do nothing (inside a long arc)
GRID = 17              # the minimax centre's coarse search along the bisector, then
GOLDEN_STEPS = 12      # golden-section steps in the best cell (its interval shrinks 0.618 a step)
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
_GRID_STEPS = np.linspace(-1.0, 1.0, GRID)  # the coarse grid's places, in 5 % of the chord either side


@dataclass(frozen=True)
class Chain:
    """A chain's points and how their numbers are written (per point ``q``, for an arc ending there)."""

    xy: np.ndarray          # (n, 2) mm, the points the arcs pass through (the current path)
    original: np.ndarray    # (n, 2) mm, the path the arcs are measured against
    target: np.ndarray      # (n, 2) the X/Y numbers of each point in its line's units and offsets
    end_scale: np.ndarray   # (n,) mm per unit of those numbers
    decimals: np.ndarray    # (n,) decimals an arc ending at the point is written with
    centre_scale: np.ndarray  # (n,) mm per unit of I/J for an arc starting at the point
    compiled: bool = False    # every batch's bounds in compiled loops (numba, where installed), however small


def fewest_blocks(chain: Chain, end: int, budget: float, min_segments: int, max_segments: int,
                  max_radius: float, lookahead: int) -> list[tuple[int, int, np.ndarray]]:
    """The arcs ``(i, q, centre)`` over points ``0..len-1`` of ``chain`` that leave the fewest blocks (an
    arc or a G1 line each), no arc ending past point ``end``, each within ``budget`` by the screen.

    Dynamic programming in the order of the starts: every arc into point ``i`` starts before it, so when
    the starts reach ``i`` its fewest blocks are known and the arcs from it are relaxed.  Exact but for two
    shortcuts: where one of the ``SKIP_GAP`` points from ``SKIP_GAP`` on has no more blocks than a start
    (inside a long arc), that start is not measured, as a later one reaches about as far (at the end of a
    long arc its last start is measured first, the others only at the ends it leaves open); and in long
    windows the ends before an end that fits are taken to fit (:func:`_measured`)."""
    n = len(chain.xy)
    blocks = np.full(n, n + 1, np.int64)
    blocks[0] = 0
    from_start = np.full(n, -1, np.int64)  # -1: reached by a G1 line from the point before
    centres = np.zeros((n, 2))
    starts = np.arange(0, max(end - min_segments + 1, 0))
    lo, idle = 0, False
    while lo < len(starts):
        if idle:  # the last chunk did nothing: pass over every chunk that would do nothing either
            skip = _idle_starts(blocks, lo, min(lo + IDLE_WINDOW, len(starts)), n) // STARTS_PER_STEP
            if skip:
                lo += skip * STARTS_PER_STEP
                continue
        chunk = starts[lo:lo + STARTS_PER_STEP]
        lo += STARTS_PER_STEP
        idle = True
        for i in chunk[chunk > 0].tolist():  # each point is reached by a line from the one before at least
            if blocks[i - 1] + 1 < blocks[i]:
                blocks[i], from_start[i] = blocks[i - 1] + 1, -1
                idle = False
        # inside a long arc every start has the same count, and a later one reaches about as far (an arc
        # from it is a part of the earlier one's): only the last starts of such a run are measured
        # (one of SKIP_GAP points that far on: a point no arc can end at, a noisy vertex, does not count)
        ahead = np.minimum(chunk[:, None] + SKIP_GAP + np.arange(SKIP_GAP)[None, :], n - 1)
        measured = chunk[(chunk + SKIP_GAP >= n) | (blocks[ahead].min(axis=1) > blocks[chunk])]
        idle &= not len(measured)
        results = {}
        groups = [measured]
        if 1 < len(measured) < len(chunk) and blocks[measured[-1]] == blocks[measured].min():
            # the end of a long arc: its last start first (no start of the chunk lowers its count), then the
            # others only past what it reaches, rather than all of them measuring the next arc's length
            groups = [measured[-1:], measured[:-1]]
        for group in groups:
            if not len(group):
                continue
            # No start of the group can bring an end below ``known`` under the fewest blocks already found
            # there: each start's count is at least the least over the group, so those ends are not measured.
            least = blocks[max(group[0] - 1, 0):group[-1] + 1].min()  # the point before: by a line
            above = np.flatnonzero(blocks[group[0]:] > least + 1)
            known = group[0] + (int(above[0]) if len(above) else n - group[0])
            for i, fits, centre in _measured(chain, group, end, budget, min_segments, max_segments, max_radius,
                                             lookahead, known, blocks > least + 1):
                results[i] = fits, centre
                if len(groups) > 1 and i == measured[-1]:
                    _relax(blocks, from_start, centres, i, fits, centre)
        for i in chunk.tolist():
            if i > 0 and blocks[i - 1] + 1 < blocks[i]:
                blocks[i], from_start[i] = blocks[i - 1] + 1, -1
            if i in results:
                _relax(blocks, from_start, centres, i, *results[i])
    for k in range(max(int(starts[-1]) + 1 if len(starts) else 1, 1), n):
        if blocks[k - 1] + 1 < blocks[k]:
            blocks[k], from_start[k] = blocks[k - 1] + 1, -1
    chosen, k = [], n - 1
    while k > 0:
        i = int(from_start[k])
        if i < 0:
            k -= 1
        else:
            chosen.append((i, k, centres[k].copy()))
            k = i
    return chosen[::-1]


def _idle_starts(blocks: np.ndarray, lo: int, hi: int, n: int) -> int:
    """How many starts from ``lo`` on (up to ``hi``) a chunk of :func:`fewest_blocks` would pass over doing
    nothing: no line from the point before lowers their count, and each is skipped by the ``SKIP_GAP`` rule
    (blocks change only where one of those happens, so the answer holds for the chunks in turn)."""
    i = np.arange(lo, hi)
    relax = (i > 0) & (blocks[np.maximum(i - 1, 0)] + 1 < blocks[i])
    ahead = np.minimum(i[:, None] + SKIP_GAP + np.arange(SKIP_GAP)[None, :], n - 1)
    measured = (i + SKIP_GAP >= n) | (blocks[ahead].min(axis=1) > blocks[i])
    busy = np.flatnonzero(relax | measured)
    return int(busy[0]) if len(busy) else hi - lo


def _relax(blocks: np.ndarray, from_start: np.ndarray, centres: np.ndarray, i: int, fits: np.ndarray,
           centre: np.ndarray) -> None:
    """The ends an arc from ``i`` reaches in fewer blocks than found so far take it."""
    ends = np.flatnonzero(fits) + 1 + i
    better = ends[blocks[i] + 1 < blocks[ends]]
    blocks[better], from_start[better] = blocks[i] + 1, i
    centres[better] = centre[better - i - 1]


def _measured(chain: Chain, chunk: np.ndarray, end: int, budget: float, min_segments: int, max_segments: int,
              max_radius: float, lookahead: int, known: int, open_end: np.ndarray):
    """Per start of ``chunk``, in order: (start, fits per end i+1.., centres).  Each start measures its ends
    from ``known`` on in windows, each twice as long as the one before, until no arc fits within
    ``lookahead`` of a window's last end or the longest allowed is reached; only the ends where
    ``open_end`` (those whose count a start of the chunk could lower) are measured, and a window with a
    closed end among its last goes on.  A window costs its open ends times its last end's length, so a
    start inside a long arc, whose arcs end just past ``known``, measures a few ends and not a block of
    them; windows stop growing at ``LAST_WINDOW`` ends (``COMPILED_LAST_WINDOW`` in compiled loops).  From
    windows of ``GALLOP`` ends on, a window's last end is measured first (its last ``lookahead`` ends where
    that one does not fit, or where the window ends at the longest arc allowed); where an arc fits there, the
    window's other open ends are taken to fit (with no centre: the caller fits those afresh), else they are
    measured in the next round."""
    limit = np.minimum(max_segments, end - chunk)  # the last end (j) each start may reach
    first = np.maximum(known - chunk, 1)
    fits = [np.zeros(max(int(n), 0), bool) for n in limit]
    centres = [np.zeros((max(int(n), 0), 2)) for n in limit]
    width = np.full(len(chunk), FIRST_WINDOW)
    longest = COMPILED_LAST_WINDOW if chain.compiled and compiled_kernels() is not None else LAST_WINDOW
    todo = first <= limit
    body_next = np.zeros(len(chunk), bool)  # a probed window whose last ends did not fit: its body is measured
    tail_next = np.zeros(len(chunk), bool)  # a probed window whose last end did not fit: its last ends next
    while todo.any():
        rows = np.flatnonzero(todo)
        last = np.minimum(first + width - 1, limit)
        tail_from = np.maximum(last - lookahead, first)  # a window's last ends
        probe = (width >= GALLOP) & ~body_next
        # a probe short of the longest arc measures the window's last end alone first (where the arc goes on,
        # the common case inside a long one, that one end is the probe's whole cost), then, where it does not
        # fit, its last ends (at the longest arc those are where arcs end: they are measured)
        alone = probe & ~tail_next & (last < limit) & open_end[chunk + last]
        ends = {}
        for r in rows:
            if alone[r]:
                ends[int(r)] = last[r:r + 1]
                continue
            span = np.arange(tail_from[r] if probe[r] else first[r],
                             (tail_from[r] - 1 if body_next[r] else last[r]) + 1)
            ends[int(r)] = span[open_end[chunk[r] + span]]
        _measure_rows(chain, chunk, [r for r in rows if len(ends[r])], ends, last, fits, centres, end, budget,
                      min_segments, max_radius)
        advance = np.zeros(len(chunk), bool)
        for r in rows:
            if alone[r] and not fits[r][last[r] - 1]:
                tail_next[r] = True  # the last end alone did not fit: the window's last ends next
                continue
            tail = np.arange(tail_from[r], last[r] + 1)
            tail_open, tail_fits = open_end[chunk[r] + tail], bool(fits[r][tail - 1].any())
            if probe[r] and not (tail_open.any() and tail_fits):
                body_next[r], tail_next[r] = True, False  # the arcs end inside the window (or nothing could tell)
                continue
            if probe[r]:  # an arc fits at the window's end: its other open ends are taken to fit too
                body = np.arange(first[r], last[r] if alone[r] else tail_from[r])
                body = body[open_end[chunk[r] + body]]
                fits[r][body - 1], centres[r][body - 1] = True, np.nan
            body_next[r], tail_next[r], advance[r] = False, False, True
            todo[r] = last[r] < limit[r] and (not tail_open.all() or tail_fits)
        first = np.where(advance, last + 1, first)
        width = np.where(advance, np.minimum(2 * width, longest), width)
    for k, i in enumerate(chunk.tolist()):
        yield i, fits[k], centres[k]


def _measure_rows(chain: Chain, chunk: np.ndarray, rows: list, ends: dict, last: np.ndarray, fits: list,
                  centres: list, end: int, budget: float, min_segments: int, max_radius: float) -> None:
    """Measure ``ends[r]`` of each start ``chunk[r]`` of ``rows`` into ``fits`` and ``centres``, as many
    starts a batch as fit in CELLS (each costs its ends times its last end's length)."""
    lo = 0
    while lo < len(rows):
        hi, cells = lo + 1, 0
        while hi < len(rows) and cells + len(ends[rows[hi]]) * (last[rows[hi]] + 1) <= CELLS:
            cells += len(ends[rows[hi]]) * (last[rows[hi]] + 1)
            hi += 1
        part = rows[lo:hi]
        j = np.zeros((len(part), max(len(ends[r]) for r in part)), np.int64)
        valid = np.zeros(j.shape, bool)
        for k, row in enumerate(part):
            j[k], valid[k, :len(ends[row])] = ends[row][0], True
            j[k, :len(ends[row])] = ends[row]
        ok, centre = _measure_ends(chain, chunk[part], j, valid, end, budget, min_segments, max_radius)
        for k, row in enumerate(part):
            fits[row][ends[row] - 1] = ok[k, valid[k]]
            centres[row][ends[row] - 1] = centre[k, valid[k]]
        lo = hi


def _measure_ends(chain: Chain, starts: np.ndarray, j: np.ndarray, valid: np.ndarray, end: int, budget: float,
                  min_segments: int, max_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """For each start ``b`` and each of its ends ``starts[b] + j[b, m]`` (``j``: (B, J), measured where
    ``valid``): whether an arc fits, and its centre (mm).  In compiled loops one candidate at a time
    (:func:`toolpath.smooth.arc_kernels.screen`) where numba is installed and the batch is large or the
    chain asks for them; else in (starts x ends x points) arrays."""
    size = int(j.max())
    kernels = compiled_kernels() if chain.compiled or j.size * (size + 1) >= COMPILED_CELLS else None
    if kernels is not None:
        fits, centre = kernels.screen(chain.xy, chain.original, chain.target, chain.decimals, chain.end_scale,
                                      chain.centre_scale, starts, j, valid, end, budget, min_segments, max_radius,
                                      _GRID_STEPS, _GOLDEN, GOLDEN_STEPS)
        return fits, centre + chain.xy[starts][:, None, :]
    k = np.arange(size + 1)
    index = np.minimum(starts[:, None] + k[None, :], len(chain.xy) - 1)  # (B, K+1)
    origin = chain.xy[starts][:, None, :]
    p = chain.xy[index] - origin  # local: no cancellation far from the machine origin
    o = chain.original[index] - origin
    chord = np.take_along_axis(p, j[..., None], axis=1)  # (B, J, 2): the end of each candidate
    length = np.hypot(chord[..., 0], chord[..., 1])
    normal = np.stack([-chord[..., 1], chord[..., 0]], axis=-1) / np.maximum(length, 1e-300)[..., None]
    inner = (k >= 1) & (k < j[..., None])  # (B, J, K+1)
    # |p - c|^2 - |c|^2 = v - 2 p.m - 2 t p.n  with c = m + t n on the bisector: linear in t
    along = np.einsum("bkd,bjd->bjk", p, normal)  # p_k . n_j
    miss = np.einsum("bkd,bkd->bk", p, p)[:, None, :] - np.einsum("bkd,bjd->bjk", p, chord)
    a = np.where(inner, 2.0 * along, 0.0)
    least = np.einsum("bjk,bjk->bj", a, miss) / np.maximum(np.einsum("bjk,bjk->bj", a, a), 1e-300)
    half = length / 2.0
    fits = np.zeros(least.shape, bool)
    centre = np.zeros(least.shape + (2,))
    # candidates (start b, end m): least squares first, then the minimax centre, then the flattest arc, each
    # tried only where the ones before did not fit (in a long smooth arc the first fits nearly every end)
    b, m = np.nonzero(valid & (j >= min_segments) & (starts[:, None] + j <= end) & (length > 0))
    for kind in ("least", "minimax", "flattest"):
        if not len(b):
            break
        if kind == "least":
            t = least[b, m]
        elif kind == "minimax":
            t = _golden(a[b, m], miss[b, m], inner[b, m], least[b, m], half[b, m])
        else:
            # a run straight within its noise (a CAM's straight edge cut in steps) has no stable algebraic
            # centre: the flattest arc allowed, bulging the way its points do, may still lie within the band
            reach = np.sqrt(np.maximum((max_radius * (1.0 - 1e-9)) ** 2 - half[b, m] ** 2, 0.0))
            t = -np.sign(np.where(inner[b, m], along[b, m], 0.0).sum(axis=-1)) * reach
        c = chord[b, m] / 2.0 + t[:, None] * normal[b, m]
        bound = _bound(chain, starts, index, p, o, b, c, j[b, m], budget)
        ok = (bound <= budget) & (np.hypot(c[:, 0], c[:, 1]) <= max_radius) & np.isfinite(bound)
        fits[b[ok], m[ok]] = True
        centre[b[ok], m[ok]] = c[ok]
        b, m = b[~ok], m[~ok]
    return fits, centre + origin


def _golden(a, miss, inner, least, half) -> np.ndarray:
    """Per candidate, the place ``t`` on the bisector where the largest radial miss of the points between,
    ``max | |p - c| - |c| |`` with ``|p - c|^2 = |c|^2 + v - 2 p.m - 2 t p.n``, is least: searched within 5 %
    of the chord around ``least``."""
    width = 0.05 * (np.abs(least) + 2.0 * half)

    def worst(t):
        radius2 = (half ** 2 + t ** 2)[..., None]
        err = np.abs(np.sqrt(np.maximum(radius2 + miss - t[..., None] * a, 0.0)) - np.sqrt(radius2))
        return np.where(inner, err, 0.0).max(axis=-1)

    # a coarse grid first (the largest miss need not have one minimum), then golden section in its best cell
    grid = _GRID_STEPS
    coarse = np.stack([worst(least + g * width) for g in grid], axis=-1)
    centre = least + grid[np.argmin(coarse, axis=-1)] * width
    cell = width * 2.0 / (GRID - 1)
    lo, hi = centre - cell, centre + cell

    x1, x2 = hi - _GOLDEN * (hi - lo), lo + _GOLDEN * (hi - lo)
    f1, f2 = worst(x1), worst(x2)
    for _ in range(GOLDEN_STEPS):
        left = f1 < f2
        hi = np.where(left, x2, hi)
        lo = np.where(left, lo, x1)
        x2n = np.where(left, x1, lo + _GOLDEN * (hi - lo))
        x1n = np.where(left, hi - _GOLDEN * (hi - lo), x2)
        x1, x2 = x1n, x2n
        fnew = worst(np.where(left, x1, x2))
        f1, f2 = np.where(left, fnew, f2), np.where(left, f1, fnew)
    return np.where(f1 < f2, x1, x2)


def _bound(chain: Chain, starts, index, p, o, rows, c, j: np.ndarray, budget: float = np.inf) -> np.ndarray:
    """:func:`toolpath.smooth.arc_weld.spiral_bound` of each candidate ``n`` (the arc about ``c[n]`` from
    point ``starts[rows[n]]`` to ``starts[rows[n]] + j[n]``, as written), its points ``p[rows[n], :j[n] + 1]``
    (local to the start; ``o``: the original's) at ``index[rows[n]]`` of the chain.  In compiled loops where
    numba is installed (:mod:`toolpath.smooth.arc_kernels`), else in NumPy arrays: the same arithmetic (the
    loops stop a candidate once past ``budget``: its figure is then only some value above it)."""
    n = np.arange(len(j))
    qi = index[rows, j]
    power = (10.0 ** chain.decimals[qi])[:, None]
    centre_scale = chain.centre_scale[starts[rows]][:, None]
    cw = np.round(c / centre_scale * power) / power * centre_scale  # I/J as written
    target = chain.target[qi]
    written_end = p[rows, j] + (np.round(target * power) / power - target) * chain.end_scale[qi][:, None]
    # the compiled loops pay numba's import (about 0.5 s and 130 MB) once: worth it on large batches only
    kernels = compiled_kernels() if chain.compiled or len(j) * p.shape[1] >= COMPILED_CELLS else None
    if kernels is not None:
        return kernels.spiral_bounds(p, o, rows, c, cw, written_end, j, budget)
    p, o = p[rows], o[rows]
    k = np.arange(p.shape[1])
    upto = k[None, :] <= j[:, None]  # (N, K+1): the vertices of each candidate
    steps = k[None, :-1] < j[:, None]  # (N, K): its segments
    s = -cw  # the start (local 0) from the centre
    e = written_end - cw
    off = o - cw[:, None, :]  # (N, K+1, 2)
    d = np.hypot(off[..., 0], off[..., 1])
    a, u = off[:, :-1], np.diff(off, axis=1)
    cross = a[..., 0] * u[..., 1] - a[..., 1] * u[..., 0]  # a x b == a x (b - a)
    dot = np.einsum("...d,...d->...", a, off[:, 1:])
    pa, pb = p[:, :-1] - c[:, None], p[:, 1:] - c[:, None]
    turn = pa[..., 0] * pb[..., 1] - pa[..., 1] * pb[..., 0]  # the fitted points' turns about the exact centre
    sign = np.sign(turn[:, :1])  # every candidate has its first segment
    one_way = np.all(~steps | ((turn * sign > 0) & (cross * sign > 0) & (dot > 0)
                               & (np.einsum("...d,...d->...", pa, pb) > 0)), axis=-1)
    step_angle = np.where(steps, np.arctan2(cross, dot) * sign, 0.0)
    theta = np.concatenate([np.zeros((len(j), 1)), np.cumsum(step_angle, axis=-1)], axis=-1)
    lead = np.arctan2(s[:, 0] * off[:, 0, 1] - s[:, 1] * off[:, 0, 0],
                      np.einsum("...d,...d->...", s, off[:, 0])) * sign[:, 0]
    sweep = np.mod(np.arctan2(s[:, 0] * e[:, 1] - s[:, 1] * e[:, 0], np.einsum("...d,...d->...", s, e))
                   * sign[:, 0], 2.0 * math.pi)
    sweep = np.where(sweep <= 0.0, 2.0 * math.pi, sweep)
    one_way &= theta[n, j] < 2.0 * math.pi - 1e-9  # each candidate's turn from its first vertex to its last
    frac = (lead[:, None] + theta) / sweep[:, None]
    interior = upto & (k[None, :] > 0) & (k[None, :] < j[:, None])
    one_way &= ~np.any(interior & ((frac < 0.0) | (frac > 1.0)), axis=-1)  # a vertex off the span: no bound
    frac = np.clip(frac, 0.0, 1.0)
    r0, r1 = np.hypot(s[:, 0], s[:, 1]), np.hypot(e[:, 0], e[:, 1])
    r = r0[:, None] + (r1 - r0)[:, None] * frac
    t = np.clip(-np.einsum("...d,...d->...", a, u) / np.maximum(np.einsum("...d,...d->...", u, u), 1e-300), 0.0, 1.0)
    nearest = np.hypot(a[..., 0] + t * u[..., 0], a[..., 1] + t * u[..., 1])
    inside = np.maximum(r[:, :-1], r[:, 1:]) - nearest
    outside = np.maximum(d[:, :-1], d[:, 1:]) - np.minimum(r[:, :-1], r[:, 1:])
    worst = np.maximum(np.where(upto, np.abs(d - r), -np.inf).max(axis=-1),
                       np.where(steps, np.maximum(inside, outside), -np.inf).max(axis=-1))
    last = off[n, j] - e  # the last vertex against the end as written
    worst = np.maximum(worst, np.hypot(last[:, 0], last[:, 1]))
    return np.where(one_way, worst, np.inf)


def compiled_kernels():
    """:mod:`toolpath.smooth.arc_kernels` when numba is installed (the ``fast`` extra), else None."""
    if importlib.util.find_spec("numba") is None:  # only numba's absence falls back: a broken kernel module fails
        return None
    from toolpath.smooth import arc_kernels

    return arc_kernels
