"""Compare the trained models of every shape: MCRL against each model on the same test programs,
a logistic-regression reference per input, and the best learned model registered in MLflow.

Run: python -m toolpath.stages.compare

Reads every model's test predictions and metrics (the train stages'); writes, per shape, ``paired``
(:func:`toolpath.models.training.replicates.paired`) and ``logistic`` figures at
:meth:`toolpath.pipeline.artifacts.Layout.comparison`, and registers the shape's best learned model (chosen on
validation, :func:`~toolpath.models.training.replicates.best_learned`) as ``models:/toolpath-<shape>@best``.
A stage of its own, so a change to one model reruns that model's training and this, not every model's.
"""

from __future__ import annotations

import argparse

from toolpath.models.registry import is_learned
from toolpath.models.training import replicates
from toolpath.pipeline import artifacts, config, model_registry, settings, tracking


def main(argv: list[str] | None = None) -> None:
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args(argv)
    cfg = config.load()
    layout = settings.layout(cfg)
    learned = [m for m in cfg.train.models if is_learned(cfg.models[m])]
    with tracking.stage_run("compare"):
        for shape in cfg.shapes:
            data = artifacts.load_windows(layout.windows_file(shape), shape)
            test_programs = data.program[data.split == artifacts.Split.TEST]
            predictions = {m: replicates.learned_predictions(artifacts.load_predictions(
                layout.test_predictions(shape, m), m)) for m in learned}
            seed = lambda kind, *names, s=shape: config.seed_for(cfg.seed, kind, s, *names)  # noqa: E731
            networks = {m: settings.plain(cfg.models[m]) for m in learned}
            figures = replicates.comparisons(predictions, networks, data.parts(), test_programs, seed)
            for kind, values in figures.items():
                artifacts.write_json(values, layout.comparison(shape, kind))
            summaries = {m: artifacts.read_json(layout.train_metrics(shape, m), f"train@{m}")["replicates"]
                         for m in cfg.train.models}
            best = replicates.best_learned(summaries)
            if best and (uri := model_registry.latest_model_uri(shape, best)):
                model_registry.register_best(shape, uri, best)


if __name__ == "__main__":
    main()
