"""Train one model of ``train.models`` on every shape, ``train.replicates`` times each with its own
seed, and evaluate every run on the held-out test programs.

Run: python -m toolpath.stages.train --model mcrl

Per shape, at the paths of :class:`toolpath.pipeline.artifacts.Layout`: the checkpoint of replicate 0, the
metrics (replicate 0's, and mean / sd / per-seed values over the replicates), every replicate's test
predictions (the compare stage pairs models on them), its per-epoch curves (Figs. 6-7) and the wall time.
One stage per model, so a change to one model's config retrains that model only; its runs on every shape
go to ``resources.workers.train`` worker processes, the longest first.
"""

from __future__ import annotations

import numpy as np

from toolpath.models.registry import is_learned, parameter_count
from toolpath.models.training import replicates
from toolpath.models.training.classifier import from_checkpoint
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import model_arg, progress


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    model = model_arg(__doc__.split("\n")[0], argv, cfg.train.models).model
    layout, common = settings.layout(cfg), cfg.train.common
    data = {shape: _windows(layout, cfg, shape) for shape in cfg.shapes}
    programs = {s: {split.label: d.program[d.split == split] for split in artifacts.Split} for s, d in data.items()}
    learned = is_learned(cfg.models[model])
    jobs = [replicates.Job(model, r, *settings.training(cfg, shape, model, r), common.class_weight, shape)
            for shape in cfg.shapes for r in range(cfg.train.replicates if learned else 1)]
    jobs = replicates.job_order(jobs, lambda j: _cost(j) if learned else 0.0)
    outcomes: dict[str, list[replicates.Outcome]] = {shape: [] for shape in cfg.shapes}
    workers = settings.workers(cfg, "train")
    with tracking.stage_run(f"train@{model}", {"replicates": cfg.train.replicates, "workers": workers,
                                               "threads": common.threads}):
        runs = replicates.run_all(jobs, {s: d.parts() for s, d in data.items()}, programs, workers, common.threads)
        for outcome in progress(runs, f"train {model}", total=len(jobs)):
            shape = outcome.job.shape
            outcomes[shape].append(outcome)
            if len(outcomes[shape]) == (cfg.train.replicates if learned else 1):
                example = data[shape].part(artifacts.Split.TEST)[0][:4].astype(np.float32)  # the logged model's input
                _save(cfg, layout, shape, model, outcomes[shape], programs[shape], example)


def _windows(layout: artifacts.Layout, cfg, shape: str) -> artifacts.WindowSet:
    """A shape's windows, refused when a split the classifier learns from or is scored on has one category."""
    data = artifacts.load_windows(layout.windows_file(shape), shape)
    for split in (artifacts.Split.TRAIN, artifacts.Split.TEST):
        present = np.unique(data.part(split)[1])
        if len(present) < 2:  # a classifier would learn, or be scored on, nothing: not a result
            raise SystemExit(f"{layout.windows_file(shape)}: the {split.label} split holds windows of "
                             f"{'category ' + str(present[0]) if len(present) else 'no category'} only; check "
                             f"label.bounds {list(cfg.label.bounds)} and label.window, then "
                             f"`dvc repro generate@{shape}`")
    return data


def _cost(job: replicates.Job) -> float:
    """Parameters x epochs: enough to run the big models first."""
    from toolpath.models.registry import build

    return parameter_count(build(job.network)) * float(job.settings.get("epochs", 0))


def _save(cfg, layout: artifacts.Layout, shape: str, model: str, runs: list, programs: dict,
          example: np.ndarray) -> None:
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
    artifacts.save_predictions(replicates.saved_predictions(runs), layout.test_predictions(shape, model))
    # the curves under their DVC plot columns (val_accuracy); val.accuracy is the final model's figure;
    # the report stage draws the confusion matrices, MLflow keeps the numbers
    finals = {k: v for k, v in config.flat(metrics).items() if isinstance(v, int | float) and not isinstance(v, bool)}
    network = from_checkpoint(first.checkpoint).network_ if first.checkpoint.get("kind") == "torch" else None
    tracking.log_model_run(f"train@{model}-{shape}", {"shape": shape, "model": model},
                           {**config.flat(first.job.network, "model"), **config.flat(first.job.settings, "train")},
                           first.history, {**finals, "train_seconds": sum(o.seconds for o in runs)},
                           {"confusion_test.json": {"confusion_test": metrics["test"]["confusion"]},
                            "checkpoint": checkpoint}, span=(first.started, first.started + first.seconds),
                           network=network, example=example)


if __name__ == "__main__":
    main()
