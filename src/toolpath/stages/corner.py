"""The NURBS corner paper's corner smoothing: PSO-solved corners, the FDLS / SDLS surrogates trained on
them, PSO's convergence study, and the W, dress and torch cases planned against two comparison
transitions.  Run: python -m toolpath.stages.corner

Writes the surrogates and each case's smoothed paths and feed profiles (for the report's figures), the
metrics (per case and method: time, peaks, bounds, curvature reductions against both 'befores', the
two-sided error; PSO's convergence study; the surrogates' test record: deterministic), one row per
corner and method (Table 2's content), the surrogates' loss curves and the timing, at the paths of
:class:`toolpath.pipeline.artifacts.Layout`.
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path

import numpy as np

from toolpath.corners.runs import (
    CORNER_FIELDS,
    pso_study,
    run_case,
    surrogate_record,
    surrogate_timing,
    train_surrogates,
)
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import pool_map, progress


def _pool_map(workers: int) -> Callable[[Callable, list, str], list]:
    return lambda fn, jobs, label: pool_map(fn, jobs, workers, label)


def main(argv: list[str] | None = None) -> None:
    import torch

    cfg = config.load()
    ccfg, layout = settings.plain(cfg.corner), settings.layout(cfg)
    corner_settings, machine, band = settings.corner(cfg), settings.machine(cfg), settings.feed_band(cfg)
    torch.set_num_threads(ccfg["threads"])
    mapper = _pool_map(settings.workers(cfg, "corner"))
    params = {"seed": cfg.seed, **config.flat(ccfg, "corner"), **config.flat(cfg.feedrate, "feedrate")}
    with tracking.stage_run("corner", params):
        import mlflow

        try:
            trained = train_surrogates(ccfg, corner_settings, cfg.seed, mapper)
        except ValueError as exc:
            raise SystemExit(f"params.yaml: {exc}") from None
        nets = (trained["nets"]["fdls"], trained["nets"]["sdls"])
        cases, rows, profiles = {}, [], {}
        for name in progress(ccfg["cases"], "corner: cases"):
            cases[name], case_rows, case_profiles = run_case(name, ccfg["methods"], nets, corner_settings, machine,
                                                             band)
            rows += case_rows
            profiles.update(case_profiles)
        seconds = {c: {m: r.pop("seconds_per_corner") for m, r in rec["methods"].items()} for c, rec in cases.items()}
        metrics = {"cases": cases, "pso_study": pso_study(ccfg, corner_settings, cfg.seed, mapper),
                   "surrogates": surrogate_record(trained)}
        artifacts.save_checkpoint({"fdls": nets[0].state_dict(), "sdls": nets[1].state_dict(), "net": ccfg["net"]},
                                  layout.surrogates)
        np.savez_compressed(layout.corner_profiles, **profiles)
        artifacts.write_json(metrics, layout.corner_metrics)
        artifacts.write_rows(rows, CORNER_FIELDS, layout.corner_rows)
        _write_curves(trained["curves"], layout.corner_curves)
        literal = {"literal": surrogate_timing(trained["literal_test"])} if "literal_test" in trained else {}
        artifacts.write_json({**surrogate_timing(trained["test"]), **literal, "cases_seconds_per_corner": seconds},
                             layout.corner_timing)
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
        for path in (layout.corner_metrics, layout.corner_rows, layout.surrogates):
            mlflow.log_artifact(str(path))


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
