"""How far the tube lets any of our methods go: the optimize stage's windows re-smoothed by a stronger
NACOA, beside the best every method reached on each window.

Sec. 5.3's dispatch (2 -> mean filter, 3 -> Bezier, 4 -> NACOA) is held to the same tube as every
method.  Whether a dispatch could reach a given reduction is bounded by what the strongest search
reaches on the same windows: here NACOA with ``factor`` x the generations the stage's study chose,
run from ``seeds`` seeds and the best of them kept *by the metric itself* (LocalCurvature, Eq. 3: an
oracle choice, so an upper estimate of what more search buys).  Per window the best of that and of
every tube result the stage wrote is an "oracle dispatch": no dispatch of these methods does better.
Reads the pipeline's outputs (``make repro`` first); never a test figure.
"""

from __future__ import annotations

import csv
import time
from dataclasses import replace

import numpy as np

from toolpath.geometry.curvature import local_curvature
from toolpath.geometry.hausdorff import hausdorff
from toolpath.pipeline import artifacts, config, settings
from toolpath.pipeline.workers import pool_map
from toolpath.smoothing.methods import nacoa_settings, problem_from
from toolpath.smoothing.nacoa import NACOA

CATEGORIES = (2, 3, 4)


def _stronger(job: tuple) -> float:
    """Reduction (%) of the best of ``seeds`` NACOA runs with ``generations`` on one window, tube mode."""
    window, ocfg, generations, seeds = job
    problem = problem_from(window, ocfg, "tube")
    run = replace(nacoa_settings(ocfg, problem.tolerance), generations=generations)
    best = min((NACOA(run).solve(problem, s).points for s in seeds), key=lambda p: float(local_curvature(p)))
    if hausdorff(window, best) > problem.tolerance + 1e-9:
        raise AssertionError("NACOA left the tube")  # the tube mode makes this impossible; never report it
    return 100.0 * (1.0 - float(local_curvature(best)) / float(local_curvature(window)))


def bench_tube_limit(shapes: list[str], factor: int = 3, seeds: int = 3, workers: int = 2) -> dict:
    cfg = config.load()
    ocfg, layout = settings.smoothing(cfg), settings.layout(cfg)
    out: dict = {"factor": factor, "seeds": seeds, "tolerance_mm": ocfg["tolerance"], "shapes": {}}
    for shape in shapes:
        summary = artifacts.read_json(layout.optimize_summary(shape), f"optimize@{shape}")
        generations = int(summary["convergence_study"]["chosen"])
        with layout.optimize_rows(shape).open(newline="") as fh:
            rows = [r for r in csv.DictReader(fh) if r["mode"] == "tube" and int(r["category"]) in CATEGORIES]
        windows = artifacts.load_windows(layout.windows_file(shape), shape).windows.astype(np.float64)
        best, category = by_window(rows)
        order = sorted(best)
        began = time.perf_counter()
        jobs = [(windows[w], ocfg, factor * generations,
                 [config.seed_for(cfg.seed, "tube_limit", shape, str(w), str(k)) for k in range(seeds)]) for w in order]
        stronger = dict(zip(order, pool_map(_stronger, jobs, workers, f"tube limit {shape}"), strict=True))
        out["shapes"][shape] = {"generations": factor * generations, "seconds": time.perf_counter() - began,
                                "per_category": limit_figures(best, category, stronger, ocfg["dispatch"])}
    return out


def by_window(rows: list[dict]) -> tuple[dict[int, dict[str, float]], dict[int, int]]:
    """The stage's tube rows as {window: {method@encoding: reduction %}} and {window: category}."""
    best: dict[int, dict[str, float]] = {}
    category: dict[int, int] = {}
    for r in rows:
        best.setdefault(int(r["window"]), {})[f"{r['method']}@{r['encoding']}"] = float(r["reduction_pct"])
        category[int(r["window"])] = int(r["category"])
    return best, category


def limit_figures(best: dict[int, dict[str, float]], category: dict[int, int], stronger: dict[int, float],
                  dispatch: dict) -> dict[str, dict]:
    """Per category and pooled (2-4): mean reduction of the stage's NACOA, the stronger NACOA, the stage's
    dispatch, and the oracle dispatch (per window the best of the stronger run and every stage result)."""
    figures = {}
    for c in (*CATEGORIES, "2-4"):
        members = [w for w in sorted(best) if c == "2-4" or category[w] == c]
        if not members:
            figures[str(c)] = {"windows": 0}
            continue
        method = {w: dispatch.get(category[w], dispatch.get(str(category[w]))) for w in members}
        figures[str(c)] = {
            "windows": len(members),
            "stage_nacoa_pct": float(np.mean([best[w]["nacoa@plain"] for w in members])),
            "stronger_nacoa_pct": float(np.mean([stronger[w] for w in members])),
            "stage_dispatch_pct": float(np.mean([best[w][f"{method[w]}@plain"] for w in members])),
            "oracle_dispatch_pct": float(np.mean([max(stronger[w], *best[w].values()) for w in members]))}
    return figures
