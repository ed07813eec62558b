"""Train one model on one shape and evaluate it on the held-out test programs.

Run: python -m toolpath.stages.train --shape gear --model mcrl

Writes the checkpoint, the test and validation metrics (deterministic for a seed), the per-epoch
curves (Figs. 6-7) and the wall time, at the paths of :class:`toolpath.artifacts.Layout`.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import torch

from toolpath import artifacts, config, settings, tracking
from toolpath.models import MODEL_NAMES
from toolpath.shapes.synth import SHAPES
from toolpath.training.classifier import fit_and_score, to_checkpoint
from toolpath.training.progress import EpochBar

PLOT_COLUMNS = ("epoch", "lr", "train_loss", "train_accuracy", "val_loss", "val_accuracy")


def _parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--shape", required=True, choices=SHAPES)
    parser.add_argument("--model", required=True, choices=MODEL_NAMES)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> None:
    args = _parse(argv)
    cfg = config.load()
    layout, common = settings.layout(cfg), cfg.train.common
    torch.set_num_threads(common.threads)
    torch.use_deterministic_algorithms(True)
    data = artifacts.load_windows(layout.windows_file(args.shape), args.shape)
    parts = data.parts()
    programs = {s.label: data.program[data.split == s] for s in artifacts.Split}
    network, train_settings = settings.training(cfg, args.shape, args.model)
    name = f"{args.shape}-{args.model}"
    params = {**config.flat(network, "model"), **config.flat(train_settings, "train"),
              "class_weight": common.class_weight}
    with tracking.stage_run(f"train@{name}", params, shape=args.shape, model=args.model):
        import mlflow

        with EpochBar(name, train_settings.get("epochs", 0) if args.model != "rule" else 0) as bar:
            clf, metrics, history, seconds = fit_and_score(network, train_settings, common.class_weight, parts,
                                                           on_epoch=bar.update, programs=programs)
        artifacts.write_json(metrics, layout.train_metrics(args.shape, args.model))
        _write_curves(history, layout.train_curves(args.shape, args.model))
        artifacts.write_json({"train_seconds": seconds, "threads": common.threads},
                             layout.train_timing(args.shape, args.model))
        checkpoint = layout.checkpoint(args.shape, args.model)
        artifacts.save_checkpoint(to_checkpoint(clf), checkpoint)
        for record in history:
            # the curves under their DVC plot columns (val_accuracy); val.accuracy is the final model's figure
            mlflow.log_metrics({k: v for k, v in vars(record).items() if k != "epoch"},
                               step=record.epoch)
        mlflow.log_metrics({k: v for k, v in config.flat(metrics).items() if isinstance(v, int | float)})
        mlflow.log_metric("train_seconds", seconds)
        # the report stage draws the confusion matrices; MLflow keeps the numbers
        mlflow.log_dict({"confusion_test": metrics["test"]["confusion"]}, "confusion_test.json")
        mlflow.log_artifact(str(checkpoint))


def _write_curves(history: list, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(PLOT_COLUMNS)
        for r in history:
            writer.writerow([r.epoch, f"{r.lr:.6g}", f"{r.train_loss:.6f}", f"{r.train_accuracy:.6f}",
                             f"{r.val_loss:.6f}", f"{r.val_accuracy:.6f}"])


if __name__ == "__main__":
    main()
