"""One trial: its config composed from ``conf/`` (:func:`toolpath.pipeline.config.compose_config`), the model trained as
the train stage would,
score it on the validation split.  The test split is never loaded: a sweep selects and reports on
validation programs only, and the test figures come from the pipeline's train stage."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig


def load_splits(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Train and val windows and labels of a windows file (``data/windows/<shape>.npz``); never test."""
    from toolpath.pipeline.artifacts import Split, load_windows

    windows = load_windows(path, path.stem)
    return {s.label: windows.part(s) for s in (Split.TRAIN, Split.VAL)}


def train_and_score(cfg: DictConfig, shape: str, model: str, threads: int,
                    splits: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
                    replicate: int = 0) -> dict[str, Any]:
    """Validation metrics (``classification_metrics``), epochs run and seconds of one training,
    exactly as the train stage trains its ``replicate`` (:func:`toolpath.models.training.classifier.fit_and_score`)."""
    from toolpath.models.training.classifier import fit_and_score
    from toolpath.models.training.replicates import deterministic_torch
    from toolpath.pipeline.settings import layout, training

    deterministic_torch(threads)
    splits = splits or load_splits(layout(cfg).windows_file(shape))
    network, settings = training(cfg, shape, model, replicate)
    _, metrics, _, seconds = fit_and_score(network, settings, cfg.train.common.class_weight, splits)
    return {**metrics, "train_seconds": seconds}


def average(results: list[dict[str, Any]]) -> dict[str, Any]:
    """The replicates of one trial as one result: every number of ``val`` (and ``test``, if given) and the epochs run
    averaged, the seconds summed.  A winner picked on one seed is picked partly for its seed; the mean
    over the train stage's replicate seeds is what the pipeline will report."""
    def mean(values: list[Any]) -> Any:
        return float(np.mean(values)) if all(isinstance(v, int | float) for v in values) else values[0]

    merged: dict[str, Any] = {split: {key: mean([r[split][key] for r in results]) for key in results[0][split]
                                      if isinstance(results[0][split][key], int | float)}
                              for split in ("val", "test") if split in results[0]}
    merged["epochs_run"] = mean([r["epochs_run"] for r in results])
    merged["train_seconds"] = float(sum(r["train_seconds"] for r in results))
    return merged


def metric(result: dict[str, Any], dotted: str) -> float:
    """``result["val"]["f1"]`` for ``"val.f1"``; a KeyError names the missing key."""
    node: Any = result
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            raise KeyError(f"objective {dotted!r}: no {part!r} in the trial's metrics")
        node = node[part]
    return float(node)
