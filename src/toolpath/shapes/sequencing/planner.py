"""Machining paths along a search order, with Xie & Zhu's collision handling (Sec. VI.B).

A plan is a list of visits.  A full visit enters a part, cuts its whole contour, then follows the
contour the shorter way to its exit (that stretch is cut twice: empty travel); a via visit only
follows an already cut contour from entry to exit.  Consecutive visits are joined by straight
transition lines, cut at feed (the ring knife never leaves the material).

Collision handling, when the transition from the current part q_m to the next p_1 meets a part
q_w of the collision area (the previous, current and next regions):
a) q_w unsearched: it joins the current region and is cut next (q_m -> q_w -> p_1);
b-I) q_w searched in the current region: its visit is removed, its neighbours are re-linked
     directly, and it is cut again next, in full (q_m -> q_w -> p_1);
b-II) q_w searched outside the region: the tool follows q_w's cut contour (q_m -> q_w -> p_1), a via
     visit that re-cuts only that stretch.
Of several colliding parts the lower-leftmost is handled first when cutting up, the upper-leftmost
when cutting down.  ``max_handling`` bounds the steps per transition: a collision left after that is
accepted and reported, never hidden.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from shapely import STRtree

from toolpath.shapes.sequencing.parts import Part
from toolpath.shapes.sequencing.transitions import best_transition


@dataclass
class Visit:
    part: int
    region: int
    entry_xy: np.ndarray
    entry_s: float
    full: bool = True
    exit_xy: np.ndarray | None = None  # None on the last visit: it ends where it entered
    exit_s: float | None = None


@dataclass
class SheetPlan:
    visits: list[Visit]
    handled: dict[str, int] = field(default_factory=lambda: {"unsearched": 0, "searched_in_region": 0,
                                                              "searched_outside": 0})

    @property
    def order(self) -> list[int]:
        return [v.part for v in self.visits if v.full]


def part_tree(parts: Sequence[Part]) -> STRtree:
    return STRtree([p.polygon for p in parts])


def plan_path(parts: Sequence[Part], order: Sequence[int], region_of: Sequence[int],
              up_of_region: Sequence[bool] | None = None, handle_collisions: bool = False,
              limit_detection: bool = True, max_handling: int = 6, tree: STRtree | None = None) -> SheetPlan:
    """Exit/entry points along ``order`` (Eq. 4-6), with collision handling when asked (Sec. VI.B).

    ``region_of[p]`` is part p's region; detection looks at regions r-1..r+1 of the current one
    when ``limit_detection`` (the paper's collision area), else at every part.  The first part is
    entered at its first contour point.
    """
    if sorted(order) != list(range(len(parts))):
        raise ValueError("the order must visit every part exactly once")
    tree = tree or part_tree(parts)
    region = np.asarray(region_of, dtype=int).copy()
    up_of_region = up_of_region or [True] * (int(region.max()) + 1)
    first = order[0]
    visits = [Visit(first, int(region[first]), parts[first].ring[0].copy(), 0.0)]
    queue: deque[tuple[int, bool]] = deque((p, True) for p in order[1:])
    searched = {first}
    plan = SheetPlan(visits)
    steps, budget = 0, max_handling * len(parts)

    def area(r: int) -> np.ndarray | None:
        return (np.abs(region - r) <= 1) if limit_detection else None

    while queue:
        nxt, full = queue[0]
        cur = visits[-1]
        choice = best_transition(parts[cur.part], cur.entry_s, parts[nxt], tree, area(cur.region))
        others = [w for w in choice.colliders if w not in (cur.part, nxt)]
        if handle_collisions and others and steps < max_handling and budget > 0:
            steps, budget = steps + 1, budget - 1
            up = up_of_region[cur.region]
            w = min(others, key=lambda i: ((parts[i].centroid[1] if up else -parts[i].centroid[1]),
                                           parts[i].centroid[0], i))
            if w not in searched:  # a)
                queue.remove((w, True))
                queue.appendleft((w, True))
                region[w] = cur.region
                plan.handled["unsearched"] += 1
                continue
            j = next((k for k, v in enumerate(visits) if v.part == w and v.full), None)
            if j is not None and 0 < j < len(visits) - 1 and visits[j].region == cur.region:  # b-I
                before, after = visits[j - 1], visits[j + 1]
                link = best_transition(parts[before.part], before.entry_s, parts[after.part], tree,
                                       area(cur.region), b_exit_s=after.exit_s)
                before.exit_xy, before.exit_s = link.exit_xy, link.exit_s
                after.entry_xy, after.entry_s = link.entry_xy, link.entry_s
                del visits[j]
                searched.discard(w)
                queue.appendleft((w, True))
                plan.handled["searched_in_region"] += 1
                continue
            queue.appendleft((w, False))  # b-II
            plan.handled["searched_outside"] += 1
            continue
        cur.exit_xy, cur.exit_s = choice.exit_xy, choice.exit_s
        visits.append(Visit(nxt, int(region[nxt]) if full else cur.region, choice.entry_xy, choice.entry_s, full))
        queue.popleft()
        if full:
            searched.add(nxt)
        steps = 0
    return plan
