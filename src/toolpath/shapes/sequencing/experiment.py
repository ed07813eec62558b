"""Every method of Xie & Zhu's comparison on one sheet, scored alike (Table 1 and the baselines)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from toolpath.shapes.sequencing.orderings import gtsp_plan, manual_order, nearest_neighbour_order
from toolpath.shapes.sequencing.planner import SheetPlan, part_tree, plan_path
from toolpath.shapes.sequencing.regions import Region, s_shaped_regions
from toolpath.shapes.sequencing.score import collisions, score
from toolpath.shapes.sequencing.sheets import Sheet

# Table 1's "optimised sorting: yes" is the S-shaped order with collision handling; "no" without.
METHODS = ("s_shaped", "s_shaped_no_avoidance", "manual", "nearest_neighbour", "gtsp", "gtsp_eq46")


@dataclass
class Outcome:
    plan: SheetPlan
    scores: dict[str, float]
    seconds: float
    facts: dict


def s_shaped(sheet: Sheet, expansions: int, start_up: bool, handle: bool, max_handling: int,
             tree=None) -> tuple[SheetPlan, list[Region]]:
    regions = s_shaped_regions(sheet.parts, expansions, start_up)
    order = [p for r in regions for p in r.order]
    region_of = [0] * len(sheet.parts)
    for k, r in enumerate(regions):
        for p in r.order:
            region_of[p] = k
    plan = plan_path(sheet.parts, order, region_of, [r.up for r in regions], handle_collisions=handle,
                     limit_detection=True, max_handling=max_handling, tree=tree)
    return plan, regions


def run_sheet(sheet: Sheet, algorithm: dict, gtsp: dict, feed: float, methods=METHODS,
              on_method: Callable[[str], None] | None = None) -> dict[str, Outcome]:
    """Plan and score ``sheet`` with each of ``methods``; ``algorithm`` and ``gtsp`` from conf/sequence."""
    parts, tree = sheet.parts, part_tree(sheet.parts)
    out: dict[str, Outcome] = {}
    for method in methods:
        began, facts = time.perf_counter(), {}
        if method in ("s_shaped", "s_shaped_no_avoidance"):
            plan, regions = s_shaped(sheet, algorithm["expansions"], algorithm["start_up"],
                                     method == "s_shaped", algorithm["max_handling"], tree)
            facts = {"regions": len(regions), **{f"handled_{k}": v for k, v in plan.handled.items()}}
        elif method == "manual":
            order, rows = manual_order(parts)
            plan = plan_path(parts, order, rows, limit_detection=False, tree=tree)
            facts = {"rows": max(rows) + 1}
        elif method == "nearest_neighbour":
            order = nearest_neighbour_order(parts, tree, algorithm["neighbours"])
            plan = plan_path(parts, order, [0] * len(parts), limit_detection=False, tree=tree)
        elif method in ("gtsp", "gtsp_eq46"):
            plan, facts = gtsp_plan(parts, gtsp["points"], gtsp["solution_limit"], gtsp["time_limit"],
                                     gtsp["metaheuristic"])
            if method == "gtsp_eq46":  # the solver's order with Eq. 4-6 exit/entry points
                plan = plan_path(parts, plan.order, [0] * len(parts), limit_detection=False, tree=tree)
        else:
            raise ValueError(f"unknown sequencing method {method!r}; choose from {', '.join(METHODS)}")
        out[method] = Outcome(plan, score(plan, parts, tree, feed), time.perf_counter() - began, facts)
        if on_method:
            on_method(method)
    return out


def plan_record(plan: SheetPlan, sheet: Sheet) -> dict:
    """Visits and collisions of a plan, as JSON (mm, 4 decimals): what the report's figure draws."""
    def xy(p):
        return None if p is None else [round(float(p[0]), 4), round(float(p[1]), 4)]
    return {"visits": [{"part": v.part, "full": v.full, "entry": xy(v.entry_xy), "exit": xy(v.exit_xy)}
                       for v in plan.visits],
            "collisions": [list(c) for c in collisions(plan, sheet.parts, part_tree(sheet.parts))]}


def outcome_records(outcomes: dict[str, Outcome]) -> tuple[dict, dict]:
    """Each method's scores and facts with its optimisation rate against the manual order (deterministic), and
    apart from them its planning seconds (Table 1's Time column: varies between runs)."""
    manual = outcomes["manual"].scores["empty_travel_mm"] if "manual" in outcomes else None
    scores = {m: {**o.scores, **{k: v for k, v in o.facts.items() if k not in ("seconds", "time_capped")},
                  "optimisation_rate_pct": None if manual is None
                  else 100.0 * (1 - o.scores["empty_travel_mm"] / manual)}
              for m, o in outcomes.items()}
    seconds = {m: {"seconds": o.seconds, "time_capped": bool(o.facts.get("time_capped", False))}
               for m, o in outcomes.items()}
    return scores, seconds
