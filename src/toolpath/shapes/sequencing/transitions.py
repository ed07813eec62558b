"""Exit and entry points between two consecutive parts (Xie & Zhu, Sec. VI.A, Eq. 4-6).

Candidate (exit on C_i, entry on C_{i+1}) pairs come from the paper's four sources: a) vertex to
vertex; b) vertex of C_i to the nearest interior point of each edge of C_{i+1}; c) the converse;
d) the closest points of the two contours.  A pair's cost (Eq. 6) is the contour travelled from
C_i's entry to its exit, the shorter way round, plus the transition line.  The cheapest pair whose
line meets C_i and C_{i+1} only at its ends (Eq. 4) and no other part of the collision area (Eq. 5)
is taken; when no such pair exists, the one meeting the fewest parts (then the cheapest) is taken
and its collisions are reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely import STRtree

from toolpath.shapes.sequencing.parts import Part

# Transition lines are shortened by this much (mm) at each end before the intersection tests, so
# touching C_i at the exit and C_{i+1} at the entry is not a collision.
END_CLEARANCE = 1e-3


@dataclass(frozen=True)
class Choice:
    """An exit on the current part and an entry on the next; ``colliders`` empty when feasible."""

    exit_xy: np.ndarray
    exit_s: float
    entry_xy: np.ndarray
    entry_s: float
    cost: float
    colliders: tuple[int, ...]


def _point_edge(points: np.ndarray, part: Part) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Nearest interior edge points of ``part`` to each of ``points``: (point idx, xy, arc position)."""
    start, vec = part.edges
    length2 = (vec ** 2).sum(axis=1)
    t = ((points[:, None, :] - start[None]) * vec[None]).sum(axis=2) / length2[None]
    i, j = np.nonzero((t > 1e-9) & (t < 1 - 1e-9))
    xy = start[j] + t[i, j, None] * vec[j]
    s = part.positions[j] + t[i, j] * np.sqrt(length2[j])
    return i, xy, s, j


def candidate_pairs(a: Part, b: Part) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every candidate from sources a-d: exit xy (m, 2), exit s (m,), entry xy (m, 2), entry s (m,)."""
    na, nb = len(a.ring), len(b.ring)
    ia, ib = np.divmod(np.arange(na * nb), nb)
    exits, exit_s = [a.ring[ia]], [a.positions[ia]]
    entries, entry_s = [b.ring[ib]], [b.positions[ib]]
    i, xy, s, _ = _point_edge(a.ring, b)  # b) vertex of C_i -> edge of C_{i+1}
    exits.append(a.ring[i]), exit_s.append(a.positions[i]), entries.append(xy), entry_s.append(s)
    i, xy, s, _ = _point_edge(b.ring, a)  # c) vertex of C_{i+1} -> edge of C_i
    exits.append(xy), exit_s.append(s), entries.append(b.ring[i]), entry_s.append(b.positions[i])
    pa, pb = np.asarray(shapely.shortest_line(a.polygon.exterior, b.polygon.exterior).coords)  # d)
    exits.append([pa]), exit_s.append([a.position_of(pa)])
    entries.append([pb]), entry_s.append([b.position_of(pb)])
    return (np.vstack(exits), np.concatenate(exit_s), np.vstack(entries), np.concatenate(entry_s))


def shortened_lines(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Transition lines less END_CLEARANCE at both ends, as shapely LineStrings."""
    vec = ends - starts
    length = np.maximum(np.hypot(*vec.T), 1e-12)[:, None]
    step = np.minimum(END_CLEARANCE, 0.49 * length) * vec / length
    return shapely.linestrings(np.stack([starts + step, ends - step], axis=1))


def line_hits(lines: np.ndarray, tree: STRtree, allowed: np.ndarray | None,
              ends: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """(line index, part index) of every part a line meets: any part of ``allowed`` (None = all) and
    its own ends (Eq. 4-5)."""
    line_idx, part_idx = tree.query(lines)  # envelopes only; the exact test below uses prepared parts
    if allowed is not None:
        keep = allowed[part_idx] | np.isin(part_idx, np.asarray(ends, dtype=part_idx.dtype))
        line_idx, part_idx = line_idx[keep], part_idx[keep]
    meets = shapely.intersects(tree.geometries[part_idx], lines[line_idx])
    return line_idx[meets], part_idx[meets]


def line_colliders(lines: np.ndarray, tree: STRtree, allowed: np.ndarray | None, ends: Sequence[int]) -> list[set[int]]:
    """For each line, the set of parts it meets (see :func:`line_hits`)."""
    hits: list[set[int]] = [set() for _ in range(len(lines))]
    for li, pi in zip(*(a.tolist() for a in line_hits(lines, tree, allowed, ends)), strict=True):
        hits[li].add(pi)
    return hits


def best_transition(a: Part, a_entry_s: float, b: Part, tree: STRtree, allowed: np.ndarray | None,
                    b_exit_s: float | None = None, batch: int = 256) -> Choice:
    """The cheapest feasible (exit, entry) pair from ``a`` (entered at ``a_entry_s``) to ``b`` (Eq. 4-6).

    ``b_exit_s`` adds the contour travel on ``b`` to a fixed exit (used when a part is re-linked after
    collision handling).  Candidates are tested in order of cost, in batches growing fourfold from
    ``batch``; the first batch usually holds the answer.
    """
    exit_xy, exit_s, entry_xy, entry_s = candidate_pairs(a, b)
    cost = a.contour_distance(a_entry_s, exit_s) + np.hypot(*(entry_xy - exit_xy).T)
    if b_exit_s is not None:
        cost = cost + b.contour_distance(entry_s, b_exit_s)
    ranked = np.lexsort((np.arange(len(cost)), cost))  # by cost, ties by candidate index: deterministic
    fallback: tuple[int, float, int] | None = None  # fewest colliders, then cost, candidate
    lo, size = 0, batch
    while lo < len(ranked):
        idx = ranked[lo:lo + size]
        li, pi = line_hits(shortened_lines(exit_xy[idx], entry_xy[idx]), tree, allowed, (a.index, b.index))
        counts = np.bincount(li, minlength=len(idx))
        free = np.flatnonzero(counts == 0)
        if len(free):
            c = idx[free[0]]
            return Choice(exit_xy[c], float(exit_s[c]), entry_xy[c], float(entry_s[c]), float(cost[c]), ())
        k = int(np.argmin(counts))
        if fallback is None or (counts[k], cost[idx[k]]) < fallback[:2]:
            fallback = (int(counts[k]), float(cost[idx[k]]), int(idx[k]))
            colliders = tuple(sorted(set(pi[li == k].tolist())))
        lo, size = lo + size, 4 * size
    c = fallback[2]
    return Choice(exit_xy[c], float(exit_s[c]), entry_xy[c], float(entry_s[c]), float(cost[c]), colliders)
