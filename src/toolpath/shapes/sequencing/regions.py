"""Region segmentation and sorting of Xie & Zhu (Sec. IV-V): the S-shaped search order.

Each molecular region (MR) is a vertical strip of parts, searched upwards or downwards, the
direction alternating from region to region, so the regions together form an S.  Inside a region
the parts are grouped into same-row regions and those into same-column regions (Sec. V.A),
whole rows are reversed by backtracking (Eq. 2-3), and every second column inside a row is
inverted (Sec. V.B, the S-shaped partial sort).

Interpretations (the text is ambiguous in these places; each choice is the one the equation states):
- Eq. 1 compares B's left boundary with A's *right boundary* ``x_ar``, as the equation says; the
  sentence after it speaks of A's centroid.
- Sec. V.A's search rule reads "downwards, from the bottom to the top" for both directions; we search
  rows bottom-to-top when cutting up and top-to-bottom when cutting down, as Fig. 1 draws it.
- Reversing a row (Eq. 2-3) reverses the order of its same-column regions; each column keeps the
  region's cutting direction until the partial sort inverts it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from toolpath.shapes.sequencing.parts import Part


@dataclass(frozen=True)
class Region:
    """One molecular region: its parts in search order, its cutting direction and inflexion part."""

    order: tuple[int, ...]
    up: bool
    inflexion: int


class _Geometry:
    """Centroids and envelope rectangles as arrays indexed by part index."""

    def __init__(self, parts: Sequence[Part]) -> None:
        self.cx = np.array([p.centroid[0] for p in parts])
        self.cy = np.array([p.centroid[1] for p in parts])
        b = np.array([p.bounds for p in parts]).reshape(-1, 4)
        self.xmin, self.ymin, self.xmax, self.ymax = b.T

    def same_row(self, a: int, b: int) -> bool:
        """B's centre lies between the lower and upper boundaries of A's envelope (Sec. V.A)."""
        return bool(self.ymin[a] <= self.cy[b] <= self.ymax[a])

    def same_column(self, a: int, b: int) -> bool:
        """B's centre lies between the left and right boundaries of A's envelope, or vice versa."""
        return bool(self.xmin[a] <= self.cx[b] <= self.xmax[a] or self.xmin[b] <= self.cx[a] <= self.xmax[b])


def inflexion_part(geo: _Geometry, pool: Sequence[int], up: bool) -> int:
    """LS, the leftmost inflexion part of ``pool`` (Sec. IV, steps 1-4 with rule f_ls of Eq. 1).

    A = the part with the smallest centroid x; S = the parts B with ``x_bl < x_ar`` and a centroid
    below A (cutting up) or above A (cutting down).  |S| = 0 gives A, |S| = 1 gives S's part,
    otherwise repeat on S.  Each round drops A, so it ends.
    """
    candidates = list(pool)
    while True:
        a = min(candidates, key=lambda i: (geo.cx[i], geo.cy[i] if up else -geo.cy[i], i))
        s = [b for b in candidates if b != a and geo.xmin[b] < geo.xmax[a]
             and (geo.cy[b] < geo.cy[a] if up else geo.cy[b] > geo.cy[a])]
        if not s:
            return a
        if len(s) == 1:
            return s[0]
        candidates = s


def molecular_region(geo: _Geometry, pool: Sequence[int], ls: int, expansions: int) -> list[int]:
    """PR grown ``expansions`` times into the MR (Sec. IV).

    PR: LS plus every candidate whose envelope's left boundary lies left of LS's centroid, or whose
    centroid lies left of LS's right boundary.  Expansion: take the region's rightmost right
    boundary and add every unsearched part whose centroid lies left of it.
    """
    region = [ls] + [c for c in pool if c != ls and (geo.xmin[c] < geo.cx[ls] or geo.cx[c] < geo.xmax[ls])]
    for _ in range(expansions):
        right = max(geo.xmax[i] for i in region)
        members = set(region)
        added = [c for c in pool if c not in members and geo.cx[c] < right]
        if not added:
            break
        region += added
    return region


def same_row_regions(geo: _Geometry, region: Sequence[int], up: bool) -> list[list[int]]:
    """Same-row regions in search order (bottom-up when cutting up), each its parts (Sec. V.A).

    Parts are taken in the preliminary order (centroid y, ascending when cutting up); the first
    unassigned part A finds its leftmost same-row sample (LSS: the leftmost part of which A is a
    right same-row sample, or A itself), and the LSS gathers every part right of it whose centre
    lies in its vertical extent.
    """
    order = sorted(region, key=lambda i: (geo.cy[i] if up else -geo.cy[i], geo.cx[i], i))
    assigned: set[int] = set()
    rows = []
    for a in order:
        if a in assigned:
            continue
        free = [b for b in order if b not in assigned]
        lefts = [b for b in free if geo.cx[b] < geo.cx[a] and geo.same_row(b, a)]
        lss = min(lefts + [a], key=lambda i: (geo.cx[i], i))
        row = [lss] + [b for b in free if b != lss and geo.cx[b] > geo.cx[lss] and geo.same_row(lss, b)]
        if a not in row:
            row.append(a)
        assigned.update(row)
        rows.append(row)
    return rows


def same_column_regions(geo: _Geometry, row: Sequence[int], up: bool) -> list[list[int]]:
    """Same-column regions of one row, left to right, each in the cutting direction (Sec. V.A)."""
    parent = {i: i for i in row}

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for k, a in enumerate(row):
        for b in row[k + 1:]:
            if geo.same_column(a, b):
                parent[root(a)] = root(b)
    groups: dict[int, list[int]] = {}
    for i in row:
        groups.setdefault(root(i), []).append(i)
    columns = [sorted(g, key=lambda i: (geo.cy[i] if up else -geo.cy[i], i)) for g in groups.values()]
    return sorted(columns, key=lambda c: (min(geo.cx[i] for i in c), c[0]))


def reverse_rows(geo: _Geometry, rows: list[list[list[int]]], ls: int, up: bool) -> list[list[list[int]]]:
    """Backtracking reversal of same-row regions (Eq. 2, and Eq. 3 for the first one).

    From the last row backwards: r_{i-1} is reversed when the first part of r_i (LB) lies left of
    the midpoint of r_{i-1}'s first and last parts (f1: x_LB < x_mid).  r_1 is reversed only when f2
    also holds: cutting up, LS's upper boundary lies below the lower boundary of r_1's leftmost part;
    cutting down, LS's lower boundary lies above that part's upper boundary.
    """
    rows = [list(r) for r in rows]
    for i in range(len(rows) - 1, 0, -1):
        first_next = rows[i][0][0]
        previous = rows[i - 1]
        mid = 0.5 * (geo.cx[previous[0][0]] + geo.cx[previous[-1][-1]])
        if not geo.cx[first_next] < mid:
            continue
        if i - 1 == 0:
            leftmost = min((p for c in previous for p in c), key=lambda p: (geo.cx[p], p))
            f2 = geo.ymax[ls] < geo.ymin[leftmost] if up else geo.ymin[ls] > geo.ymax[leftmost]
            if not f2:
                continue
        rows[i - 1] = previous[::-1]
    return rows


def partial_sort(columns: list[list[int]]) -> list[list[int]]:
    """S-shaped partial sort (Sec. V.B): invert every even-numbered column but the first and last."""
    return [c[::-1] if 1 <= k < len(columns) - 1 and (k + 1) % 2 == 0 else c for k, c in enumerate(columns)]


def s_shaped_regions(parts: Sequence[Part], expansions: int = 2, start_up: bool = True) -> list[Region]:
    """The whole search order: molecular regions with alternating cutting direction (Fig. 1)."""
    geo = _Geometry(parts)
    pool = [p.index for p in parts]
    up, regions = start_up, []
    while pool:
        ls = inflexion_part(geo, pool, up)
        members = molecular_region(geo, pool, ls, expansions)
        rows = [same_column_regions(geo, r, up) for r in same_row_regions(geo, members, up)]
        rows = [partial_sort(r) for r in reverse_rows(geo, rows, ls, up)]
        order = tuple(p for row in rows for column in row for p in column)
        regions.append(Region(order, up, ls))
        taken = set(order)
        pool = [i for i in pool if i not in taken]
        up = not up
    return regions
