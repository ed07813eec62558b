"""Baseline orders scored beside Xie & Zhu's algorithm.

- ``manual_order``: what an operator does by hand in a CAM system: rows of parts bottom to top
  (a new row starts when a centroid lies more than one median part height above the row's first),
  the rows in turn left to right and right to left (a serpentine, not a raster that runs back
  empty at every row end).  It is the reference of Table 1's optimisation rate.
- ``nearest_neighbour_order``: from the lower-left part, always the unvisited part whose best
  Eq. 4-6 transition is cheapest (collision-free ones first), among the ``k`` nearest by distance.
- ``gtsp_plan``: a generalised TSP solved by OR-Tools' routing solver: each part offers ``points``
  entry points spread evenly along its contour, exactly one is visited (a mandatory disjunction),
  the tool leaves a part where it entered (full loop, no retrace), an open path; cost = straight
  distance.  It ignores collisions: it is the empty-travel bound a pure TSP gives.  By default the
  local search descends to a local optimum and stops there (deterministic); ``guided_local_search``
  goes on for ``solution_limit`` solutions.  ``time_limit`` seconds is a safety cap, reported when it
  is what stopped the search (the result may then differ between runs).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
import shapely
from shapely import STRtree

from toolpath.shapes.sequencing.parts import Part
from toolpath.shapes.sequencing.planner import SheetPlan, Visit
from toolpath.shapes.sequencing.transitions import best_transition


def manual_order(parts: Sequence[Part]) -> tuple[list[int], list[int]]:
    """Serpentine row-by-row order and each part's row (used as its region)."""
    heights = np.array([p.bounds[3] - p.bounds[1] for p in parts])
    band = float(np.median(heights))
    by_y = sorted(parts, key=lambda p: (p.centroid[1], p.centroid[0], p.index))
    rows: list[list[Part]] = []
    for p in by_y:
        if rows and p.centroid[1] - rows[-1][0].centroid[1] <= band:
            rows[-1].append(p)
        else:
            rows.append([p])
    order, row_of = [], [0] * len(parts)
    for r, row in enumerate(rows):
        for p in sorted(row, key=lambda p: ((p.centroid[0] if r % 2 == 0 else -p.centroid[0]), p.index)):
            order.append(p.index)
            row_of[p.index] = r
    return order, row_of


def nearest_neighbour_order(parts: Sequence[Part], tree: STRtree, k: int = 6) -> list[int]:
    """Greedy order by the real transition cost (Eq. 6) from each part's actual entry point."""
    start = min(parts, key=lambda p: (p.centroid[0] + p.centroid[1], p.index)).index
    order, entry_s = [start], 0.0
    left = set(range(len(parts))) - {start}
    polygons = np.array([p.polygon for p in parts])
    while left:
        cur = parts[order[-1]]
        pool = np.array(sorted(left))
        gaps = shapely.distance(polygons[pool], cur.polygon)
        near = np.argsort(gaps, kind="stable")[:k]
        choices, cheapest = [], np.inf
        for j, gap in zip(pool[near].tolist(), gaps[near].tolist(), strict=True):
            if gap > cheapest:  # a transition is never shorter than the gap: no nearer part can win
                break
            choice = best_transition(cur, entry_s, parts[j], tree, None)
            choices.append((choice, j))
            if not choice.colliders:
                cheapest = min(cheapest, choice.cost)
        choice, nxt = min(choices, key=lambda cj: (bool(cj[0].colliders), cj[0].cost, cj[1]))
        order.append(nxt)
        entry_s = choice.entry_s
        left.discard(nxt)
    return order


def gtsp_plan(parts: Sequence[Part], points: int = 8, solution_limit: int = 2000,
              time_limit: float = 30.0, metaheuristic: str = "greedy_descent") -> tuple[SheetPlan, dict]:
    """OR-Tools generalised-TSP plan and its solver facts (status, whether the time cap stopped it)."""
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    xy, pos, owner = [np.zeros(2)], [0.0], [-1]  # node 0: a free depot (open path)
    for p in parts:
        for s in np.arange(points) * p.perimeter / points:
            xy.append(p.point_at(s))
            pos.append(float(s))
            owner.append(p.index)
    xy_arr, owner_arr = np.array(xy), np.array(owner)
    dist = np.rint(100.0 * np.hypot(*(xy_arr[:, None, :] - xy_arr[None, :, :]).transpose(2, 0, 1))).astype(np.int64)
    dist[0, :] = 0
    dist[:, 0] = 0
    manager = pywrapcp.RoutingIndexManager(len(xy), 1, 0)
    routing = pywrapcp.RoutingModel(manager)
    callback = routing.RegisterTransitMatrix(dist.tolist())  # node-indexed; no Python callback per arc
    routing.SetArcCostEvaluatorOfAllVehicles(callback)
    for p in parts:
        nodes = np.flatnonzero(owner_arr == p.index)
        routing.AddDisjunction([manager.NodeToIndex(int(n)) for n in nodes])  # no penalty: mandatory
    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
    params.local_search_metaheuristic = getattr(routing_enums_pb2.LocalSearchMetaheuristic, metaheuristic.upper())
    params.solution_limit = solution_limit
    params.time_limit.FromMilliseconds(int(1000 * time_limit))
    began = time.perf_counter()
    solution = routing.SolveWithParameters(params)
    elapsed = time.perf_counter() - began
    if solution is None:
        raise RuntimeError(f"OR-Tools found no tour (status {routing.status()})")
    index, route = routing.Start(0), []
    while not routing.IsEnd(index):
        node = manager.IndexToNode(index)
        if node:
            route.append(node)
        index = solution.Value(routing.NextVar(index))
    visits = [Visit(int(owner_arr[n]), 0, xy_arr[n].copy(), pos[n]) for n in route]
    for v in visits[:-1]:
        v.exit_xy, v.exit_s = v.entry_xy.copy(), v.entry_s
    facts = {"objective_mm": solution.ObjectiveValue() / 100.0, "seconds": elapsed,
             "time_capped": elapsed >= 0.98 * time_limit}
    return SheetPlan(visits), facts
