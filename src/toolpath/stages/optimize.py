"""Smooth a seeded sample of one shape's test windows with every method (Sec. 4.2, 5.2-5.3, Table 6).

Run: python -m toolpath.stages.optimize --shape gear

Writes the per-window rows (one per window, fidelity mode, method and encoding; ``seconds`` is the
only column that varies between runs), the summary (mean reduction, two-sided deviation, per
category, dispatch: deterministic), Table 6's timing, the convergence curves (bound mode, plain
encoding, baseline windows) and every smoothed window, at the paths of :class:`toolpath.pipeline.artifacts.Layout`.
"""

from __future__ import annotations

import csv
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import grouped_metrics, progress, shape_arg
from toolpath.smoothing.evaluate import ROW_FIELDS, summarise, timing
from toolpath.smoothing.methods import dispatch
from toolpath.smoothing.runs import convergence_curves, plan, run_task, sample_windows


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    args = shape_arg(__doc__.split("\n")[0], argv, cfg.shapes)
    ocfg, layout = settings.smoothing(cfg), settings.layout(cfg)
    data = artifacts.load_windows(layout.windows_file(args.shape), args.shape)
    # the seed names stay "optimise" (the stage's former name): renaming them would change every draw
    chosen = sample_windows(data.label, data.split, ocfg["sample"], config.seed_for(cfg.seed, "optimise", args.shape))
    try:
        tasks = plan(chosen, ocfg)
    except ValueError as exc:
        raise SystemExit(f"params.yaml: {exc}") from None
    windows = data.windows.astype(np.float64)
    # one seed per window and mode, shared by every method: the same start and the same draws
    jobs = [(t, windows[t["window"]], ocfg, config.seed_for(cfg.seed, "optimise", args.shape, str(t["window"]),
                                                             t["mode"])) for t in tasks]
    params = {**config.flat(ocfg, "optimize"), "windows": len(chosen), "runs": len(tasks)}
    with tracking.stage_run(f"optimize@{args.shape}", params, shape=args.shape):
        import mlflow

        # spawn, not fork: the parent holds MLflow's threads; results do not depend on the worker count
        with ProcessPoolExecutor(ocfg["workers"], mp_context=multiprocessing.get_context("spawn")) as pool:
            # results in submission order, so the output does not depend on which worker finished first
            futures = [pool.submit(run_task, job) for job in jobs]
            outputs = [future.result() for future in progress(futures, f"optimize {args.shape}")]
        rows = [o[0] for o in outputs]
        mapping = {int(k): v for k, v in ocfg["dispatch"].items()}
        categories = sorted({c for _, c, _ in chosen})
        summary = summarise(rows, {c: dispatch(c, mapping) for c in categories})
        summary["sample"] = {"windows": len(chosen), "runs": len(tasks),
                             "per_category": {str(c): sum(1 for _, k, _ in chosen if k == c) for c in categories}}
        artifacts.write_rows(rows, ROW_FIELDS, layout.optimize_rows(args.shape))
        artifacts.write_json(summary, layout.optimize_summary(args.shape))
        artifacts.write_json(timing(rows), layout.optimize_timing(args.shape))
        _write_curves(convergence_curves(tasks, outputs), layout.optimize_curves(args.shape))
        # float64: float32 rounding of coordinates near 100 mm (~4 um) would break the tolerance on reload
        artifacts.save_smoothed(artifacts.SmoothedSet(
            points=np.stack([o[1] for o in outputs]), window=np.array([t["window"] for t in tasks]),
            method=np.array([t["method"] for t in tasks]), mode=np.array([t["mode"] for t in tasks]),
            encoding=np.array([t["encoding"] for t in tasks])), layout.smoothed_file(args.shape))
        mlflow.log_metrics(grouped_metrics(summary["methods"], {"mean_reduction_pct": "mean_reduction_pct",
                                                                "max_hausdorff_mm": "max_hausdorff_mm"}))
        for step, row in enumerate(rows):
            mlflow.log_metric(f"reduction_pct.{row['mode']}.{row['encoding']}.{row['method']}", row["reduction_pct"],
                              step=step)
        mlflow.log_artifact(str(layout.optimize_rows(args.shape)))
        mlflow.log_artifact(str(layout.optimize_summary(args.shape)))


def _write_curves(curves: dict[str, np.ndarray], path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(list(curves))
        for i in range(len(curves["budget_fraction"])):
            writer.writerow([f"{values[i]:.6g}" for values in curves.values()])


if __name__ == "__main__":
    main()
