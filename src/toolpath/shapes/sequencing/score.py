"""Empty travel, collisions and machining time of a plan: one scoring for every method.

Empty travel (Xie & Zhu, Table 1) is everything the tool travels besides cutting each contour once:
the transition lines plus the stretches of contour travelled a second time (from a part's entry to
its exit after the full cut, and along via visits).  A collision is a transition line meeting a part
anywhere but at its own two ends (Eq. 4-5), checked against every part on the sheet, not only the
collision area the planner looks at.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence

import numpy as np
from shapely import STRtree

from toolpath.shapes.sequencing.parts import Part
from toolpath.shapes.sequencing.planner import SheetPlan
from toolpath.shapes.sequencing.transitions import line_colliders, shortened_lines


def transitions(plan: SheetPlan) -> tuple[np.ndarray, np.ndarray]:
    """Start (exit) and end (entry) points of every transition line, (k, 2) each."""
    starts = np.array([v.exit_xy for v in plan.visits[:-1]]).reshape(-1, 2)
    ends = np.array([v.entry_xy for v in plan.visits[1:]]).reshape(-1, 2)
    return starts, ends


def collisions(plan: SheetPlan, parts: Sequence[Part], tree: STRtree) -> list[tuple[int, int]]:
    """(transition index, part index) for every part a transition line meets beyond its ends."""
    starts, ends = transitions(plan)
    if not len(starts):
        return []
    hits = line_colliders(shortened_lines(starts, ends), tree, None, ())
    return [(k, p) for k, h in enumerate(hits) for p in sorted(h)]


def score(plan: SheetPlan, parts: Sequence[Part], tree: STRtree, feed: float) -> dict[str, float]:
    """Scores of ``plan``; ``feed`` (mm/min) converts path length into machining time.

    Raises ValueError when a part is not cut in full exactly once.
    """
    counts = Counter(v.part for v in plan.visits if v.full)
    wrong = [p.index for p in parts if counts[p.index] != 1]
    if wrong:
        raise ValueError(f"the plan does not cut parts {wrong[:10]} exactly once")
    starts, ends = transitions(plan)
    line = float(np.hypot(*(ends - starts).T).sum()) if len(starts) else 0.0
    retrace = sum(float(parts[v.part].contour_distance(v.entry_s, v.exit_s))
                  for v in plan.visits if v.exit_s is not None)
    cut = sum(p.perimeter for p in parts)
    hits = collisions(plan, parts, tree)
    return {
        "empty_travel_mm": line + retrace,
        "transition_mm": line,
        "retrace_mm": retrace,
        "cut_mm": cut,
        "collisions": len(hits),
        "colliding_transitions": len({k for k, _ in hits}),
        "via_visits": sum(not v.full for v in plan.visits),
        "machining_time_s": 60.0 * (cut + line + retrace) / feed,
    }
