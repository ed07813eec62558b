"""What the train stage (and every sweep trial) trains: a model config and its training settings."""

from __future__ import annotations

from typing import Any

from omegaconf import DictConfig, OmegaConf

from toolpath import config
from toolpath.models.registry import split_schedule


def model_and_settings(cfg: DictConfig, shape: str, model: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """The network config of ``models.<model>`` and the settings of ``train.<shape>`` + ``train.common``.

    ``train.common.lr``, when set, replaces every shape's learning rate; a ``schedule`` inside the
    model config (a tuned model) overrides both, being the most specific.  The seed derives from the
    global seed, the shape and the model, so a sweep trial trains what the stage would.
    """
    common = cfg.train.common
    network, schedule = split_schedule(OmegaConf.to_container(cfg.models[model], resolve=True))
    shared = {"lr": common.lr} if common.get("lr") is not None else {}
    settings = {**OmegaConf.to_container(cfg.train[shape], resolve=True), **shared, **schedule,
                "patience": common.patience, "weight_decay": common.weight_decay, "augment": common.augment,
                "aux_loss_weight": common.aux_loss_weight, "seed": config.seed_for(cfg.seed, "train", shape, model)}
    return network, settings
