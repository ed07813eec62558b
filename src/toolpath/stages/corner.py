"""The NURBS corner paper's corner smoothing: PSO-solved corners, the FDLS / SDLS surrogates trained on them, and the
W, dress and torch cases planned against two comparison transitions.  Run: python -m toolpath.stages.corner

Writes ``<paths.corner>/surrogates.pt`` (FDLS and SDLS), ``<paths.corner>/profiles.npz`` (each case's
smoothed path and planned feed profile per method, for the report's figures),
``<paths.metrics>/corner.json`` (per case and method: time, peaks, bounds, curvature reduction and
error; the surrogates' test record: deterministic), ``<paths.metrics>/corner_corners.csv`` (one row
per corner and method, Table 2's content), ``<paths.plots>/corner/training.csv`` (the loss curves of
Figs. 8-9) and ``<paths.timing>/corner.json`` (seconds per corner, PSO against the surrogates).
"""

from __future__ import annotations

import csv
import math
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from toolpath import config, tracking
from toolpath.feedrate.assess import assess
from toolpath.feedrate.limits import Machine, polyline_radius
from toolpath.optimize.corner import PsoSettings, evaluate
from toolpath.optimize.corner_path import CornerSettings, arc_blend_curvature, corner_smoother, smooth_path
from toolpath.shapes.cases import case_path
from toolpath.stages._common import progress, write_json, write_rows

CORNER_FIELDS = ("case", "method", "vertex", "turn_deg", "leg", "curvature_before", "curvature_method1",
                 "curvature_after", "reduction_pct", "reduction_vs_method1_pct", "error_mm", "inside", "source")


def _solve(job: tuple) -> tuple:
    from toolpath.optimize.corner_net import solve

    corner, seed, delta_max, settings = job
    return solve(corner, seed, delta_max, settings)


def settings_from(ccfg: dict, fcfg: dict, seed: int) -> CornerSettings:
    return CornerSettings(delta_max=ccfg["delta_max"], min_turn_deg=ccfg["min_turn_deg"], max_leg=ccfg["max_leg"],
                          blend_tolerance=fcfg["blend_tolerance"], curve_samples=ccfg["curve_samples"],
                          line_step=ccfg["line_step"], pso=PsoSettings(**ccfg["pso"], seed=seed))


def train_surrogates(ccfg: dict, settings: CornerSettings, seed: int) -> dict:
    """Solve the drawn corners by PSO, fit FDLS and SDLS on the training part, test on the rest."""
    import torch

    from toolpath.optimize.corner_net import ResidualMLP, draw_corners, fdls_data, fit, sdls_data, smooth_corner

    data = ccfg["dataset"]
    drawn = draw_corners(data["train"] + data["test"], config.seed_for(seed, "corner", "dataset"),
                         tuple(math.radians(t) for t in data["turns_deg"]), tuple(data["legs"]))
    jobs = [(corner, s, settings.delta_max, settings.pso) for corner, s in drawn]
    # spawn, not fork: the parent holds MLflow's threads; results do not depend on the worker count
    with ProcessPoolExecutor(ccfg["workers"], mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(_solve, job) for job in jobs]
        solved = [f.result() for f in progress(futures, "corner: PSO dataset")]
    train = [s for s, _ in solved[:data["train"]] if s is not None]
    if len(train) < 2:
        raise SystemExit(f"params.yaml: corner.dataset: PSO solved only {len(train)} training corners; "
                         "draw more or widen corner.pso")
    nets, curves = {}, {}
    for name, (X, Y) in (("fdls", fdls_data(train)), ("sdls", sdls_data(train))):
        torch.manual_seed(config.seed_for(seed, "corner", name))
        net = ResidualMLP(X.shape[1], Y.shape[1], **ccfg["net"])
        curves[name] = fit(net, X, Y, ccfg[name]["epochs"], ccfg[name]["batch"], ccfg[name]["lr"],
                           config.seed_for(seed, "corner", name, "fit"))
        nets[name] = net
    test = []
    for (corner, _), (sample, pso_seconds) in zip(drawn[data["train"]:], solved[data["train"]:], strict=True):
        started = time.perf_counter()
        # as on the case paths: an answer sharper than the circular blend goes back to PSO
        found, source = smooth_corner(nets["fdls"], nets["sdls"], corner, settings.delta_max, settings.pso,
                                      arc_blend_curvature(corner, settings.delta_max))
        net_seconds = time.perf_counter() - started
        pso_curvature = None
        if sample is not None:
            pso_curvature = evaluate(corner, sample.points, sample.weights, settings.delta_max).max_curvature
        test.append({"source": source, "feasible": found is not None and found.feasible,
                     "net_curvature": found.max_curvature if found is not None else None,
                     "pso_curvature": pso_curvature, "net_seconds": net_seconds, "pso_seconds": pso_seconds})
    return {"nets": nets, "curves": curves, "test": test, "train_size": len(train),
            "pso_failures": sum(s is None for s, _ in solved)}


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
    from toolpath.optimize.corner_study import solve_grid

    return solve_grid(*job)


def pso_study(ccfg: dict, settings: CornerSettings, seed: int) -> dict:
    """PSO's convergence over particles x iterations on drawn corners (their own seeded draw)."""
    from toolpath.optimize.corner_net import draw_corners
    from toolpath.optimize.corner_study import summarise_grid

    study, data = ccfg["pso_study"], ccfg["dataset"]
    drawn = draw_corners(study["corners"], config.seed_for(seed, "corner", "pso_study"),
                         tuple(math.radians(t) for t in data["turns_deg"]), tuple(data["legs"]))
    jobs = [(corner, settings.delta_max, PsoSettings(**{**settings.pso.__dict__, "seed": s}), study["particles"],
             study["iterations"]) for corner, s in drawn]
    with ProcessPoolExecutor(ccfg["workers"], mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(_study, job) for job in jobs]
        grids = [f.result() for f in progress(futures, "corner: PSO convergence study")]
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
        done = [c for c in smoothed.corners if c.source != "kept"]
        record["methods"][method] = {
            **planned,
            "corners": len(smoothed.corners), "kept_sharp": len(smoothed.corners) - len(done),
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


def main(argv: list[str] | None = None) -> None:
    import torch

    cfg = config.load()
    ccfg = OmegaConf.to_container(cfg.corner, resolve=True)
    fcfg = OmegaConf.to_container(cfg.feedrate, resolve=True)
    machine = Machine(**fcfg["machine"])
    band = math.inf if fcfg["band"] is None else float(fcfg["band"])
    settings = settings_from(ccfg, fcfg, config.seed_for(cfg.seed, "corner", "pso"))
    torch.set_num_threads(ccfg["threads"])
    out = Path(cfg.paths.corner)
    metrics_dir = Path(cfg.paths.metrics)
    params = {"seed": cfg.seed, **config.flat(ccfg, "corner"), **config.flat(fcfg, "feedrate")}
    with tracking.stage_run("corner", params):
        import mlflow

        trained = train_surrogates(ccfg, settings, cfg.seed)
        nets = (trained["nets"]["fdls"], trained["nets"]["sdls"])
        cases, rows, profiles = {}, [], {}
        for name in progress(ccfg["cases"], "corner: cases"):
            cases[name], case_rows, case_profiles = run_case(name, ccfg["methods"], nets, settings, machine, band)
            rows += case_rows
            profiles.update(case_profiles)
        seconds = {c: {m: r.pop("seconds_per_corner") for m, r in rec["methods"].items()} for c, rec in cases.items()}
        metrics = {"cases": cases, "pso_study": pso_study(ccfg, settings, cfg.seed),
                   "surrogates": {**surrogate_summary(trained["test"]), "train_corners": trained["train_size"],
                                  "pso_failures": trained["pso_failures"],
                                  "final_loss": {k: v[-1] for k, v in trained["curves"].items()}}}
        out.mkdir(parents=True, exist_ok=True)
        torch.save({"fdls": nets[0].state_dict(), "sdls": nets[1].state_dict(), "net": ccfg["net"]},
                   out / "surrogates.pt")
        np.savez_compressed(out / "profiles.npz", **profiles)
        write_json(metrics, metrics_dir / "corner.json")
        write_rows(rows, CORNER_FIELDS, metrics_dir / "corner_corners.csv")
        _write_curves(trained["curves"], Path(cfg.paths.plots) / "corner" / "training.csv")
        test = trained["test"]
        write_json({"pso_seconds_per_corner": float(np.mean([t["pso_seconds"] for t in test])) if test else None,
                    "surrogate_seconds_per_corner": float(np.mean([t["net_seconds"] for t in test])) if test else None,
                    "cases_seconds_per_corner": seconds},
                   Path(cfg.paths.timing) / "corner.json")
        for case, rec in cases.items():
            mlflow.log_metric(f"{case}.g01.time_s", rec["g01"]["time"])
            for method, r in rec["methods"].items():
                mlflow.log_metrics({f"{case}.{method}.time_s": r["time"],
                                    f"{case}.{method}.time_saved_vs_g01_pct": r["time_saved_vs_g01_pct"]})
                mlflow.log_metrics({f"{case}.{method}.{k}": v for k, v in r.items()
                                    if k.endswith(("reduction_pct", "reduction_vs_method1_pct", "error_mm"))
                                    and v is not None})
        for name, curve in trained["curves"].items():
            for epoch, loss in enumerate(curve):
                mlflow.log_metric(f"{name}.train_mse", loss, step=epoch)
        mlflow.log_artifact(str(metrics_dir / "corner.json"))
        mlflow.log_artifact(str(metrics_dir / "corner_corners.csv"))
        mlflow.log_artifact(str(out / "surrogates.pt"))


def _write_curves(curves: dict[str, list[float]], path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    epochs = max(len(c) for c in curves.values())
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["epoch", *(f"{k}_mse" for k in curves)])
        for e in range(epochs):
            writer.writerow([e + 1, *(f"{c[e]:.6g}" if e < len(c) else "" for c in curves.values())])


if __name__ == "__main__":
    main()
