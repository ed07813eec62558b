"""How fast any planner could run the corner cases: the planner beside the time-optimal bound, with the
tangential jerk limit as configured and lifted, over a few tangential accelerations.

The corner stage times each case path (G01 with the controller blend, and each smoothed path) under the
NURBS corner paper's planner, whose S-curve ramps hold the tangential jerk limit, beside toppra's
time-optimal bound, which has no jerk limit.  Two questions a reader of that table asks, answered here:

- **Is the gap to the bound the planner's or the jerk limit's?**  The same planner, read point by point
  (a curve at each sample's own limit, not each sensitive run at its lowest) and with the tangential
  jerk limit lifted (:data:`LIFTED`: each S-curve becomes a trapezoid), is timed beside the bound; where
  the two agree, what is left of the gap is what the interval rule and the jerk limit cost.
- **Can smoothing save time under these limits at all?**  The bound orders the G01 path and the smoothed
  path as each runs at its fastest under the limits without the jerk limit: where the G01 path's bound
  is the lower, the smoothed path cannot be the faster when both run time-optimally.  (With the jerk
  limit no such bound is computed here: a planner could be further from the optimum on one path than on
  the other.)  Repeated at higher tangential accelerations (the corner speed matters more when the tool
  slows and speeds up quickly), it shows where the order turns.

Run: ``python -m toolpath.bench --only planner`` -> ``reports/bench/planner_limit.json``.  Smooths the
case paths itself (NURBS + PSO, dual Bezier, B-spline; the surrogates need the pipeline's networks).
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from toolpath.corners.cases import case_path
from toolpath.corners.path import corner_smoother, smooth_path
from toolpath.feedrate.bounds import toppra_time
from toolpath.feedrate.limits import Machine, polyline_radius
from toolpath.feedrate.planner import plan

LIFTED = 1e9  # x the tangential acceleration: a jerk limit this high leaves each ramp 1e-9 s of jerk phase
METHODS = ("nurbs_pso", "bezier", "bspline")


def lifted(machine: Machine) -> Machine:
    """``machine`` with its tangential jerk limit lifted (S-curve ramps become trapezoids)."""
    return dataclasses.replace(machine, tangential_jerk=machine.tangential_acceleration * LIFTED)


def times(points: np.ndarray, rho: np.ndarray, machine: Machine, straight: bool, band: float) -> dict[str, float]:
    """Seconds: the planner as configured (``band``); read point by point (``band`` 0: a sensitive interval
    per distinct limit, so a curve runs at each sample's own limit), with and without the tangential jerk
    limit; toppra's bound.  On a G01 path the reading makes no difference (its limits bind at vertices)."""
    return {"planner": plan(points, rho, machine, straight=straight, band=band).time,
            "pointwise": plan(points, rho, machine, straight=straight, band=0.0).time,
            "pointwise_without_jerk_limit": plan(points, rho, lifted(machine), straight=straight, band=0.0).time,
            "toppra_bound": toppra_time(points, rho, machine, straight=straight)}


def measure(cases: list[str], corner_settings, machine: Machine, band: float, accelerations: list[float],
            methods: tuple[str, ...] = METHODS) -> dict:
    """Per tangential acceleration, case and path (``g01`` and each method): the four times of :func:`times`,
    each over the bound (%), and each method's time saved against the G01 path under each (%)."""
    paths: dict[str, dict[str, tuple[np.ndarray, np.ndarray, bool]]] = {}
    for case in cases:
        points = case_path(case)
        paths[case] = {"g01": (points, polyline_radius(points, corner_settings.blend_tolerance), True)}
        for method in methods:
            smoothed = smooth_path(points, corner_smoother(method), corner_settings)
            paths[case][method] = (smoothed.points, smoothed.rho, False)
    out: dict = {}
    for acceleration in accelerations:
        limits = dataclasses.replace(machine, tangential_acceleration=acceleration)
        rows: dict = {}
        for case, by_path in paths.items():
            rows[case] = {name: times(points, rho, limits, straight, band)
                          for name, (points, rho, straight) in by_path.items()}
            g01 = rows[case]["g01"]
            for method in methods:
                row = rows[case][method]
                row["saved_vs_g01_pct"] = {k: 100.0 * (1.0 - row[k] / g01[k]) for k in g01}
            for row in rows[case].values():
                row["planner_over_bound_pct"] = 100.0 * (row["planner"] / row["toppra_bound"] - 1.0)
                row["pointwise_without_jerk_limit_over_bound_pct"] = \
                    100.0 * (row["pointwise_without_jerk_limit"] / row["toppra_bound"] - 1.0)
        out[f"{acceleration:g}"] = rows
    return out


def bench_planner_limit(accelerations_factor: tuple[float, ...] = (1.0, 2.5, 5.0)) -> dict:
    """:func:`measure` on the corner stage's cases at the configured limits and ``accelerations_factor`` x
    the configured tangential acceleration (the normal limits stay as configured)."""
    from toolpath.pipeline import config, settings

    cfg = config.load()
    machine, corner_settings = settings.machine(cfg), settings.corner(cfg)
    started = time.perf_counter()
    accelerations = [machine.tangential_acceleration * f for f in accelerations_factor]
    result = measure(list(cfg.corner.cases), corner_settings, machine, settings.feed_band(cfg), accelerations)
    return {"machine": dataclasses.asdict(machine), "band": None if cfg.feedrate.band is None else cfg.feedrate.band,
            "blend_tolerance_mm": corner_settings.blend_tolerance, "delta_max_mm": corner_settings.delta_max,
            "jerk_lifted_to": f"{LIFTED:g} x the tangential acceleration", "by_tangential_acceleration": result,
            "seconds": time.perf_counter() - started}
