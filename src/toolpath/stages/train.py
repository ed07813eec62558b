"""Train one model on one shape and evaluate it on the held-out test programs.

Run: python -m toolpath.stages.train --shape gear --model mcrl

Writes ``models/<shape>/<model>.pt``, ``<metrics>/train/<shape>/<model>.json`` (test and
validation metrics, deterministic for a seed), ``reports/plots/train/<shape>/<model>.csv``
(per-epoch curves, Figs. 6-7) and ``reports/timing/train/<shape>/<model>.json`` (wall time).
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import torch

from toolpath import config, tracking
from toolpath.models import MODEL_NAMES, build
from toolpath.reports.figures import confusion_figure
from toolpath.shapes.synth import SHAPES
from toolpath.stages._common import load_windows, save_checkpoint, write_json
from toolpath.training.classifier import TorchClassifier, to_checkpoint
from toolpath.training.metrics import classification_metrics
from toolpath.training.progress import EpochBar
from toolpath.training.setup import model_and_settings

PLOT_COLUMNS = ("epoch", "lr", "train_loss", "train_accuracy", "val_loss", "val_accuracy")


def _parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--shape", required=True, choices=SHAPES)
    parser.add_argument("--model", required=True, choices=MODEL_NAMES)
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> None:
    args = _parse(argv)
    cfg = config.load()
    common = cfg.train.common
    torch.set_num_threads(common.threads)
    torch.use_deterministic_algorithms(True)
    data = load_windows(Path(cfg.paths.windows) / f"{args.shape}.npz")
    parts = {name: (data["windows"][data["split"] == k], data["label"][data["split"] == k])
             for k, name in enumerate(("train", "val", "test"))}
    network, settings = model_and_settings(cfg, args.shape, args.model)
    name = f"{args.shape}-{args.model}"
    params = {**config.flat(network, "model"), **config.flat(settings, "train"), "class_weight": common.class_weight}
    with tracking.stage_run(f"train@{name}", params, shape=args.shape, model=args.model):
        import mlflow

        start = time.perf_counter()
        if args.model == "rule":
            clf, history = build(network).fit(parts["train"][0]), []
        else:
            with EpochBar(name, settings["epochs"]) as bar:
                clf = TorchClassifier(network, settings, common.class_weight).fit(
                    *parts["train"], *parts["val"], on_epoch=bar.update)
            history = clf.history_
        seconds = time.perf_counter() - start
        metrics = {split: classification_metrics(parts[split][1], clf.predict_proba(parts[split][0]))
                   for split in ("val", "test")}
        metrics["epochs_run"] = len(history)
        out = Path(cfg.paths.metrics) / "train" / args.shape / f"{args.model}.json"
        write_json(metrics, out)
        _write_curves(history, Path(cfg.paths.plots) / "train" / args.shape / f"{args.model}.csv")
        write_json({"train_seconds": seconds, "threads": common.threads},
                   Path(cfg.paths.timing) / "train" / args.shape / f"{args.model}.json")
        save_checkpoint(to_checkpoint(clf), Path(cfg.paths.models) / args.shape / f"{args.model}.pt")
        for record in history:
            mlflow.log_metrics({f"{k.replace('_', '/', 1)}": v for k, v in vars(record).items() if k != "epoch"},
                               step=record.epoch)
        mlflow.log_metrics({k: v for k, v in config.flat(metrics).items() if isinstance(v, int | float)})
        mlflow.log_metric("train_seconds", seconds)
        mlflow.log_figure(confusion_figure(metrics["test"]["confusion"], f"{name} (test)"), "confusion_test.png")
        mlflow.log_artifact(str(Path(cfg.paths.models) / args.shape / f"{args.model}.pt"))


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
