"""Smooth a seeded sample of one shape's test windows with every method (Sec. 4.2, 5.2-5.3, Table 6).

Run: python -m toolpath.stages.optimize --shape gear

Writes, under ``<paths.metrics>/optimize/``: ``<shape>.csv`` (one row per window, fidelity mode,
method and encoding; the ``seconds`` column is the only one that varies between runs) and
``<shape>.json`` (mean reduction, deviation, per category, dispatch: deterministic); under
``<paths.timing>/optimize/<shape>.json`` Table 6's time, evaluations, complexity and Eq. 34
efficiency; ``<paths.plots>/optimize/<shape>.csv`` convergence curves (bound mode, plain encoding,
baseline windows); and ``<paths.smoothed>/<shape>.npz`` every smoothed window, for the report.
"""

from __future__ import annotations

import csv
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from toolpath import config, tracking
from toolpath.optimize.evaluate import ROW_FIELDS, convergence, summarise, timing, window_row
from toolpath.optimize.mealpy_runs import MEALPY_CLASSES
from toolpath.optimize.methods import BASELINE_ONLY, METHODS, dispatch, smooth
from toolpath.shapes.synth import SHAPES
from toolpath.stages._common import grouped_metrics, load_windows, progress, shape_arg, write_json, write_rows

TEST = 2


def sample_windows(label: np.ndarray, split: np.ndarray, sample: dict, seed: int) -> list[tuple[int, int, bool]]:
    """(window index, category, runs the baselines) for a seeded draw of test windows per category."""
    rng = np.random.default_rng(seed)
    chosen = []
    for category in sample["categories"]:
        pool = np.flatnonzero((label == category) & (split == TEST))
        picks = rng.choice(pool, size=min(sample["per_category"], len(pool)), replace=False)
        with_baselines = category in sample["baseline_categories"]
        chosen += [(int(i), int(category), with_baselines and k < sample["baselines_per_category"])
                   for k, i in enumerate(picks)]
    return chosen


def plan(chosen: list[tuple[int, int, bool]], ocfg: dict) -> list[dict]:
    """Every (window, mode, method, encoding) to run; mealpy methods (both encodings) and NACOA with the
    paper's permuting initialisation only on the baseline windows."""
    unknown = [m for m in ocfg["methods"] if m not in METHODS]
    if unknown:
        raise SystemExit(f"params.yaml: optimize.methods has unknown method(s) {', '.join(unknown)}; "
                         f"known: {', '.join(METHODS)}")
    tasks = []
    for index, category, baselines in chosen:
        for mode in ocfg["modes"]:
            for method in ocfg["methods"]:
                if method in BASELINE_ONLY and not baselines:
                    continue
                for encoding in ocfg["encodings"] if method in MEALPY_CLASSES else ["plain"]:
                    tasks.append({"window": index, "category": category, "baseline_window": baselines,
                                  "mode": mode, "method": method, "encoding": encoding})
    return tasks


def _run(job: tuple[dict, np.ndarray, dict, int]) -> tuple[dict, np.ndarray, list[float]]:
    task, window, ocfg, seed = job
    result = smooth(window, task["method"], ocfg, task["mode"], seed, task["encoding"])
    return window_row(window, result, **task), result.points, result.history


def main(argv: list[str] | None = None) -> None:
    args = shape_arg(__doc__.split("\n")[0], argv, SHAPES)
    cfg = config.load()
    ocfg = OmegaConf.to_container(cfg.optimize, resolve=True)
    data = load_windows(Path(cfg.paths.windows) / f"{args.shape}.npz")
    chosen = sample_windows(data["label"], data["split"], ocfg["sample"],
                            config.seed_for(cfg.seed, "optimise", args.shape))
    tasks = plan(chosen, ocfg)
    windows = data["windows"].astype(np.float64)
    # one seed per window and mode, shared by every method: the same start and the same draws
    jobs = [(t, windows[t["window"]], ocfg, config.seed_for(cfg.seed, "optimise", args.shape, str(t["window"]),
                                                             t["mode"])) for t in tasks]
    params = {**config.flat(ocfg, "optimize"), "windows": len(chosen), "runs": len(tasks)}
    with tracking.stage_run(f"optimize@{args.shape}", params, shape=args.shape):
        import mlflow

        # spawn, not fork: the parent holds MLflow's threads; results do not depend on the worker count
        with ProcessPoolExecutor(ocfg["workers"], mp_context=multiprocessing.get_context("spawn")) as pool:
            # results in submission order, so the output does not depend on which worker finished first
            futures = [pool.submit(_run, job) for job in jobs]
            outputs = [future.result() for future in progress(futures, f"optimize {args.shape}")]
        rows = [o[0] for o in outputs]
        mapping = {int(k): v for k, v in ocfg["dispatch"].items()}
        categories = sorted({c for _, c, _ in chosen})
        summary = summarise(rows, {c: dispatch(c, mapping) for c in categories})
        summary["sample"] = {"windows": len(chosen), "runs": len(tasks),
                             "per_category": {str(c): sum(1 for _, k, _ in chosen if k == c) for c in categories}}
        metrics_dir = Path(cfg.paths.metrics) / "optimize"
        write_rows(rows, ROW_FIELDS, metrics_dir / f"{args.shape}.csv")
        write_json(summary, metrics_dir / f"{args.shape}.json")
        write_json(timing(rows), Path(cfg.paths.timing) / "optimize" / f"{args.shape}.json")
        _write_convergence(tasks, outputs, Path(cfg.paths.plots) / "optimize" / f"{args.shape}.csv")
        smoothed = Path(cfg.paths.smoothed) / f"{args.shape}.npz"
        smoothed.parent.mkdir(parents=True, exist_ok=True)
        # float64: float32 rounding of coordinates near 100 mm (~4 um) would break the tolerance on reload
        np.savez_compressed(smoothed, points=np.stack([o[1] for o in outputs]),
                            window=np.array([t["window"] for t in tasks]),
                            method=np.array([t["method"] for t in tasks]), mode=np.array([t["mode"] for t in tasks]),
                            encoding=np.array([t["encoding"] for t in tasks]))
        mlflow.log_metrics(grouped_metrics(summary["methods"], {"mean_reduction_pct": "mean_reduction_pct",
                                                                "max_hausdorff_mm": "max_hausdorff_mm"}))
        for step, row in enumerate(rows):
            mlflow.log_metric(f"reduction_pct.{row['mode']}.{row['encoding']}.{row['method']}", row["reduction_pct"],
                              step=step)
        mlflow.log_artifact(str(metrics_dir / f"{args.shape}.csv"))
        mlflow.log_artifact(str(metrics_dir / f"{args.shape}.json"))


def _write_convergence(tasks: list[dict], outputs: list, path: Path) -> None:
    """Mean convergence per optimiser in ``bound`` mode, plain encoding, on the windows every
    optimiser ran (the baseline windows; all windows when no baseline ran)."""
    baseline_windows = {t["window"] for t in tasks if t["method"] in MEALPY_CLASSES}
    histories: dict[str, list] = {}
    for task, (row, _, history) in zip(tasks, outputs, strict=True):
        if (history and task["mode"] == "bound" and task["encoding"] == "plain"
                and (not baseline_windows or task["window"] in baseline_windows)):
            histories.setdefault(task["method"], []).append((history, row["fitness_before"]))
    curves = convergence(histories)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(list(curves))
        for i in range(len(curves["budget_fraction"])):
            writer.writerow([f"{values[i]:.6g}" for values in curves.values()])


if __name__ == "__main__":
    main()
