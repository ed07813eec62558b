"""The corner stage's work as functions: the PSO-solved corner set and the FDLS / SDLS surrogates
trained on it, PSO's convergence study, and each case path smoothed by every corner method, planned
and checked (the NURBS corner paper's cases 1-3).  Parallel work goes through a ``pool_map(fn, jobs,
label)`` the caller supplies (results in job order, whatever the worker count)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from toolpath.corners.cases import case_path
from toolpath.corners.curve import evaluate
from toolpath.corners.path import (
    CornerSettings,
    corner_smoother,
    smooth_path,
    surrogate_corner,
    surrogate_limit,
)
from toolpath.corners.pso import PsoSettings
from toolpath.feedrate.assess import assess
from toolpath.feedrate.limits import Machine, polyline_radius
from toolpath.pipeline.seeds import seed_for

PoolMap = Callable[[Callable, list, str], list]
CORNER_FIELDS = ("case", "method", "vertex", "turn_deg", "leg", "curvature_before", "curvature_method1",
                 "curvature_after", "reduction_pct", "reduction_vs_method1_pct", "error_mm", "inside", "source")


def _solve(job: tuple) -> tuple:
    from toolpath.corners.network import solve

    corner, seed, delta_max, settings = job
    return solve(corner, seed, delta_max, settings)


def train_surrogates(ccfg: dict, settings: CornerSettings, seed: int, pool_map: PoolMap) -> dict:
    """Solve the drawn corners by PSO (through ``pool_map``), fit FDLS and SDLS on the training part with
    its targets held inside the checks by ``dataset.margin`` (:func:`held_inside`), test on the rest;
    with a margin, networks fitted on PSO's answers as found are tested beside (``literal_test``)."""
    from toolpath.corners.network import draw_corners, held_inside

    data = ccfg["dataset"]
    margin = data.get("margin") or {"delta": 0.0, "wedge": 0.0}
    if not all(0.0 <= float(margin[k]) < 1.0 for k in ("delta", "wedge")):
        raise ValueError(f"corner.dataset.margin {dict(margin)}: delta and wedge are fractions in [0, 1)")
    drawn = draw_corners(data["train"] + data["test"], seed_for(seed, "corner", "dataset"),
                         tuple(math.radians(t) for t in data["turns_deg"]), tuple(data["legs"]))
    solved = pool_map(_solve, [(corner, s, settings.delta_max, settings.pso) for corner, s in drawn],
                      "corner: PSO dataset")
    train = [s for s, _ in solved[:data["train"]] if s is not None]
    if len(train) < 2:
        raise ValueError(f"corner.dataset: PSO solved only {len(train)} training corners; "
                         "draw more or widen corner.pso")
    targets = [held_inside(s, settings.delta_max, margin["delta"], margin["wedge"],
                           surrogate_limit(s.corner, settings.delta_max)) for s in train]
    literal = bool(margin["delta"] or margin["wedge"])  # the paper's way too, for the record: what the margin buys
    fitted = _fit(ccfg, [targets, train] if literal else [targets], seed, pool_map)
    (nets, curves), held_out = fitted[0], (drawn[data["train"]:], solved[data["train"]:])
    trained = {"nets": nets, "curves": curves, "test": _test(nets, *held_out, settings), "train_size": len(train),
               "held_inside": sum(t is not s for t, s in zip(targets, train, strict=True)), "margin": margin,
               "pso_failures": sum(s is None for s, _ in solved)}
    if literal:
        trained["literal_test"] = _test(fitted[1][0], *held_out, settings)
    return trained


NETS = ("fdls", "sdls")


def _fit(ccfg: dict, sample_sets: list[list], seed: int, pool_map: PoolMap) -> list[tuple[dict, dict]]:
    """FDLS and SDLS fitted on each set of samples: per set, (nets, loss curves).  The fits are independent
    (each seeds its own initialisation and shuffling and runs on ``corner.threads`` threads in its process),
    so they go through ``pool_map`` side by side, the FDLS fits (more steps: a smaller batch) first."""
    from toolpath.corners.network import ResidualMLP, fdls_data, sdls_data

    data = [{"fdls": fdls_data(samples), "sdls": sdls_data(samples)} for samples in sample_sets]
    jobs = [(ccfg, name, *data[k][name], seed) for name in NETS for k in range(len(sample_sets))]
    states = iter(pool_map(_fit_one, jobs, "corner: FDLS / SDLS"))
    fitted: list[tuple[dict, dict]] = [({}, {}) for _ in sample_sets]
    for name in NETS:
        for k in range(len(sample_sets)):
            state, curve = next(states)
            X, Y = data[k][name]
            net = ResidualMLP(X.shape[1], Y.shape[1], **ccfg["net"])
            net.load_state_dict(state)
            fitted[k][0][name], fitted[k][1][name] = net.eval(), curve
    return fitted


def _fit_one(job: tuple) -> tuple[dict, list[float]]:
    """One network fitted (in a worker process): its weights and loss curve."""
    import torch

    from toolpath.corners.network import ResidualMLP, fit

    ccfg, name, X, Y, seed = job
    torch.set_num_threads(ccfg["threads"])  # results are reproducible per thread count: the stage's, always
    torch.manual_seed(seed_for(seed, "corner", name))
    net = ResidualMLP(X.shape[1], Y.shape[1], **ccfg["net"])
    curve = fit(net, X, Y, ccfg[name]["epochs"], ccfg[name]["batch"], ccfg[name]["lr"],
                seed_for(seed, "corner", name, "fit"))
    return net.state_dict(), curve


def _test(nets: dict, drawn: list, solved: list, settings: CornerSettings) -> list[dict]:
    """Each held-out corner answered by the networks (checked, repaired or sent back to PSO) against
    PSO's own answer."""
    test = []
    for (corner, _), (sample, pso_seconds) in zip(drawn, solved, strict=True):
        started = time.perf_counter()
        # as on the case paths: an answer sharper than method 1 at delta_max goes back to PSO
        found, source = surrogate_corner((nets["fdls"], nets["sdls"]), corner, settings.delta_max, settings.pso,
                                         surrogate_limit(corner, settings.delta_max))
        net_seconds = time.perf_counter() - started
        pso_curvature = None
        if sample is not None:
            pso_curvature = evaluate(corner, sample.points, sample.weights, settings.delta_max).max_curvature
        test.append({"source": source, "feasible": found is not None and found.feasible,
                     "net_curvature": found.max_curvature if found is not None else None,
                     "pso_curvature": pso_curvature, "net_seconds": net_seconds, "pso_seconds": pso_seconds})
    return test


def surrogate_record(trained: dict) -> dict:
    """The surrogates' deterministic record for the metrics file."""
    record = {**surrogate_summary(trained["test"]), "train_corners": trained["train_size"],
              "pso_failures": trained["pso_failures"], "final_loss": {k: v[-1] for k, v in trained["curves"].items()},
              "held_inside": trained["held_inside"], "margin": trained["margin"]}
    if "literal_test" in trained:
        record["literal"] = surrogate_summary(trained["literal_test"])
    return record


def surrogate_timing(test: list[dict]) -> dict:
    """Seconds per held-out corner, PSO against the surrogates (varies between runs)."""
    return {"pso_seconds_per_corner": float(np.mean([t["pso_seconds"] for t in test])) if test else None,
            "surrogate_seconds_per_corner": float(np.mean([t["net_seconds"] for t in test])) if test else None}


def surrogate_summary(test: list[dict]) -> dict:
    both = [t for t in test if t["pso_curvature"] and t["net_curvature"]]
    return {
        "test_corners": len(test),
        "sources": {s: sum(t["source"] == s for t in test) for s in ("net", "repaired", "pso", "infeasible")},
        "feasible": sum(t["feasible"] for t in test),
        "curvature_ratio_to_pso": float(np.mean([t["net_curvature"] / t["pso_curvature"] for t in both]))
        if both else None,
    }


def reductions(values: list[float], suffix: str) -> dict:
    """Mean, worst (smallest) and best reduction of the smoothed corners, per cent (None if none)."""
    return {f"mean_reduction{suffix}_pct": float(np.mean(values)) if values else None,
            f"worst_reduction{suffix}_pct": min(values, default=None),
            f"max_reduction{suffix}_pct": max(values, default=None)}


def _study(job: tuple) -> np.ndarray:
    from toolpath.corners.study import solve_grid

    return solve_grid(*job)


def pso_study(ccfg: dict, settings: CornerSettings, seed: int, pool_map: PoolMap) -> dict:
    """PSO's convergence over particles x iterations on drawn corners (their own seeded draw)."""
    from toolpath.corners.network import draw_corners
    from toolpath.corners.study import summarise_grid

    study, data = ccfg["pso_study"], ccfg["dataset"]
    drawn = draw_corners(study["corners"], seed_for(seed, "corner", "pso_study"),
                         tuple(math.radians(t) for t in data["turns_deg"]), tuple(data["legs"]))
    jobs = [(corner, settings.delta_max, PsoSettings(**{**settings.pso.__dict__, "seed": s}), study["particles"],
             study["iterations"]) for corner, s in drawn]
    grids = pool_map(_study, jobs, "corner: PSO convergence study")
    return summarise_grid(grids, study["particles"], study["iterations"], study["enough"])


def run_case(name: str, methods: list[str], nets: tuple, settings: CornerSettings, machine: Machine,
             band: float) -> tuple[dict, list[dict], dict]:
    """The G01 path and each method's smoothed path, planned and checked: (record, corner rows, profiles)."""
    points = case_path(name)
    plan_g01, g01 = assess(points, polyline_radius(points, settings.blend_tolerance), machine, straight=True, band=band)
    record = {"g01": g01, "methods": {}}
    rows, profiles = [], {f"{name}/path": points, f"{name}/g01/t": plan_g01.t, f"{name}/g01/v": plan_g01.v}
    for method in methods:
        smoothed = smooth_path(points, corner_smoother(method, nets), settings)
        result, planned = assess(smoothed.points, smoothed.rho, machine, straight=False, band=band)
        done = [c for c in smoothed.corners if not c.source.startswith("kept")]
        record["methods"][method] = {
            **planned,
            "corners": len(smoothed.corners), "kept_sharp": len(smoothed.corners) - len(done),
            "answers": {source: sum(c.source == source for c in done) for source in sorted({c.source for c in done})},
            **reductions([c.reduction_pct for c in done], ""),
            **reductions([c.reduction_vs_method1_pct for c in done if math.isfinite(c.curvature_method1)],
                         "_vs_method1"),
            "max_error_mm": max((c.error for c in done), default=None),  # two-sided, exact
            "all_inside": all(c.inside for c in done),
            "seconds_per_corner": float(np.mean([c.seconds for c in smoothed.corners])) if smoothed.corners else 0.0,
            "time_saved_vs_g01_pct": 100.0 * (1.0 - planned["time"] / g01["time"]),
        }
        rows += [{"case": name, "method": method, "vertex": c.vertex, "turn_deg": c.turn_deg, "leg": c.leg,
                  "curvature_before": c.curvature_before, "curvature_method1": c.curvature_method1,
                  "curvature_after": c.curvature_after, "reduction_pct": c.reduction_pct,
                  "reduction_vs_method1_pct": c.reduction_vs_method1_pct, "error_mm": c.error, "inside": c.inside,
                  "source": c.source} for c in smoothed.corners]
        profiles.update({f"{name}/{method}/path": smoothed.points, f"{name}/{method}/t": result.t,
                         f"{name}/{method}/v": result.v})
    for method, entry in record["methods"].items():  # the paper's comparison: time saved against each other method
        entry["time_saved_vs_pct"] = {other: 100.0 * (1.0 - entry["time"] / o["time"])
                                      for other, o in record["methods"].items() if other != method}
    return record, rows, profiles
