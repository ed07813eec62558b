"""Smooth a seeded sample of one shape's test windows with every method (Sec. 4.2, 5.2-5.3, Table 6).

Run: python -m toolpath.stages.optimize --shape gear

First studies on validation windows choose NACOA's generation count and, per fidelity mode, the mean
filter's and Bezier's settings.  Writes the
per-window rows (one per window, fidelity mode, method and encoding; ``seconds`` is the only column
that varies between runs), the summary (deterministic: the paper's metric on categories 2-4 with
intervals, the old all-category means, per category, dispatch, the study), Table 6's timing, the
convergence curves and every smoothed window, at the paths of :class:`toolpath.pipeline.artifacts.Layout`.
"""

from __future__ import annotations

import numpy as np

from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.warm_pool import process_pool
from toolpath.pipeline.workers import grouped_metrics, progress, shape_arg
from toolpath.smoothing import runs
from toolpath.smoothing.evaluate import ROW_FIELDS, timing


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    args = shape_arg(__doc__.split("\n")[0], argv, cfg.shapes)
    ocfg, layout = settings.smoothing(cfg), settings.layout(cfg)
    data = artifacts.load_windows(layout.windows_file(args.shape), args.shape)
    # the seed names stay "optimise" (the stage's former name): renaming them would change every draw
    seed = lambda *names: config.seed_for(cfg.seed, "optimise", args.shape, *names)  # noqa: E731
    chosen = runs.sample_windows(data.label, data.split, ocfg["sample"], seed())
    try:
        tasks = runs.plan(chosen, ocfg)
        runs.smoother_grid(ocfg["smoother_study"])
    except ValueError as exc:
        raise SystemExit(f"params.yaml: {exc}") from None
    windows = data.windows.astype(np.float64)
    study = ocfg["convergence_study"]
    studied = runs.study_windows(data.label, data.split, study, seed("study"))
    tuned_on = runs.study_windows(data.label, data.split, ocfg["smoother_study"], seed("smoother_study"))
    params = {**config.flat(ocfg, "optimize"), "windows": len(chosen), "runs": len(tasks)}
    with tracking.stage_run(f"optimize@{args.shape}", params, shape=args.shape):
        import mlflow

        # not forked from here: the parent holds MLflow's threads; results do not depend on the worker count
        with process_pool(settings.workers(cfg, "optimize")) as pool:
            cells = [(windows[i], g, ocfg, seed("study", str(i))) for g in study["generations"] for i in studied]
            fits = [f.result() for f in progress([pool.submit(runs.run_study_task, c) for c in cells],
                                                  f"NACOA study {args.shape}")]
            counts = list(study["generations"])
            chosen_study = runs.choose_generations(counts, np.reshape(fits, (len(counts), -1)), study["within_pct"])
            ocfg = {**ocfg, "nacoa": {**ocfg["nacoa"], "generations": chosen_study["chosen"]}}
            smoothers = runs.study_smoothers(pool, [windows[i] for i in tuned_on], ocfg)
            by_mode = runs.settings_by_mode(ocfg, smoothers)
            # one seed per window and mode, shared by every method: the same start and the same draws
            jobs = [(t, windows[t["window"]], by_mode[t["mode"]], seed(str(t["window"]), t["mode"])) for t in tasks]
            # results in submission order, so the output does not depend on which worker finished first
            futures = [pool.submit(runs.run_task, job) for job in jobs]
            outputs = [future.result() for future in progress(futures, f"optimize {args.shape}")]
        mlflow.log_params({"nacoa_generations_chosen": chosen_study["chosen"], **config.flat(
            {m: {k: v["chosen"] for k, v in node.items()} for m, node in smoothers["modes"].items()}, "chosen")})
        rows = [o[0] for o in outputs]
        summary = runs.summarise_run(rows, chosen, tasks, ocfg, chosen_study,
                                     seed(ocfg["sample"]["bootstrap_seed_name"]), smoothers)
        artifacts.write_rows(rows, ROW_FIELDS, layout.optimize_rows(args.shape))
        artifacts.write_json(summary, layout.optimize_summary(args.shape))
        artifacts.write_json(timing(rows), layout.optimize_timing(args.shape))
        curves = runs.convergence_curves(tasks, outputs)
        artifacts.write_rows([{k: v[i] for k, v in curves.items()} for i in range(len(curves["budget_fraction"]))],
                             list(curves), layout.optimize_curves(args.shape))
        # float64: float32 rounding of coordinates near 100 mm (~4 um) would break the tolerance on reload
        artifacts.save_smoothed(artifacts.SmoothedSet(
            points=np.stack([o[1] for o in outputs]), window=np.array([t["window"] for t in tasks]),
            method=np.array([t["method"] for t in tasks]), mode=np.array([t["mode"] for t in tasks]),
            encoding=np.array([t["encoding"] for t in tasks])), layout.smoothed_file(args.shape))
        mlflow.log_metrics(grouped_metrics(summary["methods"], {"all_categories_reduction_pct": "mean_reduction_pct",
                                                                "max_hausdorff_mm": "max_hausdorff_mm"}))
        mlflow.log_metrics({f"cat2_4_reduction_pct.{mode}.{method}": v["categories_2_4"]["mean_reduction_pct"]
                            for mode, node in summary["paper_metric"].items()
                            for method, v in node["methods"].items() if v["categories_2_4"]})
        for step, row in enumerate(rows):
            mlflow.log_metric(f"reduction_pct.{row['mode']}.{row['encoding']}.{row['method']}", row["reduction_pct"],
                              step=step)
        mlflow.log_artifact(str(layout.optimize_rows(args.shape)))
        mlflow.log_artifact(str(layout.optimize_summary(args.shape)))


if __name__ == "__main__":
    main()
