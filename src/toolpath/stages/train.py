"""Train every model of ``train.models`` on one shape, ``train.replicates`` times each with its own
seed, and evaluate every run on the held-out test programs.

Run: python -m toolpath.stages.train --shape gear

Per model, at the paths of :class:`toolpath.pipeline.artifacts.Layout`: the checkpoint of replicate 0, the
metrics (replicate 0's, and mean / sd / per-seed values over the replicates), its per-epoch curves
(Figs. 6-7) and the wall time.  One process per shape: the runs go to ``resources.workers.train`` worker
processes, so the pipeline does not pay interpreter and MLflow start-up once per model.
"""

from __future__ import annotations

import numpy as np

from toolpath.models.registry import parameter_count
from toolpath.models.training import replicates
from toolpath.models.training.classifier import from_checkpoint
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import progress, shape_arg


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    args = shape_arg(__doc__.split("\n")[0], argv, cfg.shapes)
    layout, common = settings.layout(cfg), cfg.train.common
    data = artifacts.load_windows(layout.windows_file(args.shape), args.shape)
    for split in (artifacts.Split.TRAIN, artifacts.Split.TEST):
        present = np.unique(data.part(split)[1])
        if len(present) < 2:  # a classifier would learn, or be scored on, nothing: not a result
            raise SystemExit(f"{layout.windows_file(args.shape)}: the {split.label} split holds windows of "
                             f"{'category ' + str(present[0]) if len(present) else 'no category'} only; check "
                             f"label.bounds {list(cfg.label.bounds)} and label.window, then "
                             f"`dvc repro generate@{args.shape}`")
    programs = {s.label: data.program[data.split == s] for s in artifacts.Split}
    jobs = [replicates.Job(model, r, *settings.training(cfg, args.shape, model, r), common.class_weight)
            for model in cfg.train.models for r in range(cfg.train.replicates if _learned(cfg, model) else 1)]
    jobs = replicates.job_order(jobs, lambda j: _cost(j, cfg))
    outcomes: dict[str, list[replicates.Outcome]] = {m: [] for m in cfg.train.models}
    saved: dict[str, tuple[str | None, dict]] = {}  # model: (its MLflow model URI, its seed summary)
    example = data.part(artifacts.Split.TEST)[0][:4].astype(np.float32)  # the logged models' input example
    workers = settings.workers(cfg, "train")
    with tracking.stage_run(f"train@{args.shape}", {"replicates": cfg.train.replicates, "workers": workers,
                                                   "threads": common.threads}, shape=args.shape):
        runs = replicates.run_all(jobs, data.parts(), programs, workers, common.threads)
        for outcome in progress(runs, f"train {args.shape}", total=len(jobs)):
            outcomes[outcome.job.model].append(outcome)
            if len(outcomes[outcome.job.model]) == (cfg.train.replicates if _learned(cfg, outcome.job.model) else 1):
                saved[outcome.job.model] = _save_model(cfg, layout, args.shape, outcome.job.model,
                                                       outcomes[outcome.job.model], programs, example)
        learned = {m: cfg.models[m] for m in cfg.train.models if _learned(cfg, m)}
        seed = lambda kind, *names: config.seed_for(cfg.seed, kind, args.shape, *names)  # noqa: E731
        for name, figures in replicates.comparisons(outcomes, learned, data.parts(), programs["test"], seed).items():
            artifacts.write_json(figures, layout.train_metrics(args.shape, name))
        uris, summaries = {m: u for m, (u, _) in saved.items()}, {m: s for m, (_, s) in saved.items()}
        if (best := replicates.best_learned(summaries)) and uris.get(best):
            tracking.register_best(args.shape, uris[best], best)


def _learned(cfg, model: str) -> bool:
    from toolpath.models.registry import is_learned

    return is_learned(cfg.models[model])


def _cost(job: replicates.Job, cfg) -> float:
    """Parameters x epochs: enough to run the big models first."""
    from toolpath.models.registry import build

    return parameter_count(build(job.network)) * float(job.settings.get("epochs", 0)) if _learned(cfg, job.model) else 0


def _save_model(cfg, layout: artifacts.Layout, shape: str, model: str, runs: list, programs: dict,
                example: np.ndarray) -> tuple[str | None, dict]:
    runs = sorted(runs, key=lambda o: o.job.replicate)
    first = runs[0]
    summary = replicates.summarise(runs, programs["test"], config.seed_for(cfg.seed, "bootstrap", shape, model))
    metrics = {**first.metrics, "replicates": summary}
    artifacts.write_json(metrics, layout.train_metrics(shape, model))
    artifacts.write_curves(first.history, layout.train_curves(shape, model))
    artifacts.write_json({"train_seconds": [o.seconds for o in runs], "threads": cfg.train.common.threads},
                         layout.train_timing(shape, model))
    checkpoint = layout.checkpoint(shape, model)
    artifacts.save_checkpoint(first.checkpoint, checkpoint)
    # the curves under their DVC plot columns (val_accuracy); val.accuracy is the final model's figure;
    # the report stage draws the confusion matrices, MLflow keeps the numbers
    finals = {k: v for k, v in config.flat(metrics).items() if isinstance(v, int | float) and not isinstance(v, bool)}
    network = from_checkpoint(first.checkpoint).network_ if first.checkpoint.get("kind") == "torch" else None
    uri = tracking.log_model_run(f"train@{shape}-{model}", {"shape": shape, "model": model},
                           {**config.flat(first.job.network, "model"), **config.flat(first.job.settings, "train")},
                           first.history, {**finals, "train_seconds": sum(o.seconds for o in runs)},
                           {"confusion_test.json": {"confusion_test": metrics["test"]["confusion"]},
                            "checkpoint": checkpoint}, span=(first.started, first.started + first.seconds),
                           network=network, example=example)
    return uri, summary


if __name__ == "__main__":
    main()
