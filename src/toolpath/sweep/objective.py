"""One trial: compose its config from ``conf/`` with Hydra, train the model as the train stage would,
score it on the validation split (the test split is reported, never selected on)."""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf


def compose(root: Path, overrides: Sequence[str]) -> DictConfig:
    """``conf/config.yaml`` of ``root`` composed with ``overrides`` and resolved, as ``dvc exp run`` does."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(Path(root).resolve() / "conf"), version_base=None):
        cfg = hydra_compose(config_name="config", overrides=list(overrides))
    OmegaConf.resolve(cfg)
    return cfg


def load_splits(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Train / val / test windows and labels of a windows file (``data/windows/<shape>.npz``)."""
    if not path.is_file():
        shape = path.stem
        raise FileNotFoundError(f"{path}: windows file not found; run `dvc repro label@{shape}` first")
    with np.load(path) as data:
        windows, label, split = data["windows"], data["label"], data["split"]
    return {name: (windows[split == k], label[split == k]) for k, name in enumerate(("train", "val", "test"))}


def train_and_score(cfg: DictConfig, shape: str, model: str, threads: int,
                    splits: dict[str, tuple[np.ndarray, np.ndarray]] | None = None) -> dict[str, Any]:
    """Validation and test metrics (``classification_metrics``), epochs run and seconds of one training."""
    import torch

    from toolpath.training.classifier import TorchClassifier
    from toolpath.training.metrics import classification_metrics
    from toolpath.training.setup import model_and_settings

    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(True)
    splits = splits or load_splits(Path(cfg.paths.windows) / f"{shape}.npz")
    network, settings = model_and_settings(cfg, shape, model)
    start = time.perf_counter()
    clf = TorchClassifier(network, settings, cfg.train.common.class_weight).fit(*splits["train"], *splits["val"])
    seconds = time.perf_counter() - start
    out = {split: classification_metrics(splits[split][1], clf.predict_proba(splits[split][0]))
           for split in ("val", "test")}
    return {**out, "epochs_run": len(clf.history_), "train_seconds": seconds}


def metric(result: dict[str, Any], dotted: str) -> float:
    """``result["val"]["f1"]`` for ``"val.f1"``; a KeyError names the missing key."""
    node: Any = result
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            raise KeyError(f"objective {dotted!r}: no {part!r} in the trial's metrics")
        node = node[part]
    return float(node)
