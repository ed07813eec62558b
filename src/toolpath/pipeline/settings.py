"""Every settings object the stages and the sweep use, built from the composed config in one place.

Stages and the sweep call these; domain packages receive the objects (dataclasses, plain dicts) and
never read the config.  Each builder passes a config node to its dataclass with ``**``, so an unknown
key there fails at once instead of being ignored.  The seeds derive from the global seed and stable
names (:func:`toolpath.pipeline.config.seed_for`); those names never change, so neither do the results.
"""

from __future__ import annotations

import math
from typing import Any

from omegaconf import DictConfig, OmegaConf

from toolpath.pipeline import config
from toolpath.pipeline.artifacts import Layout


def plain(node: Any) -> Any:
    """A config node as plain Python containers (resolved)."""
    return OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) or OmegaConf.is_list(node) \
        else node


def workers(cfg: DictConfig, stage: str) -> int:
    """Worker processes for ``stage`` (``resources.workers``, a group no stage declares: outputs do not
    depend on it)."""
    return int(cfg.resources.workers[stage])


def layout(cfg: DictConfig) -> Layout:
    return Layout.from_config(plain(cfg.paths))


def build(node: Any, **extra: Any) -> Any:
    """The object a config node with ``_target_`` describes (Hydra's ``instantiate``); every key must be
    an argument of the target, so a misspelt or dead key fails here (and in tests/test_config.py)."""
    from hydra.utils import instantiate

    return instantiate(node, _convert_="all", **extra)


def reader_options(cfg: DictConfig):
    """The G-code reader's options (``gcode.read``)."""
    return build(cfg.gcode.read)


def program_spec(cfg: DictConfig, **extra: Any):
    """The G-code writer's program settings (``gcode.write``)."""
    return build(cfg.gcode.write, **extra)


def bounds(cfg: DictConfig) -> tuple[float, float, float]:
    """Table 1's LocalCurvature thresholds (``label.bounds``): labelling, the rule and the report use them."""
    low, mid, high = (float(b) for b in cfg.label.bounds)
    return low, mid, high


# ---- training ------------------------------------------------------------------------------------
def training(cfg: DictConfig, shape: str, model: str, replicate: int = 0) -> tuple[dict[str, Any], dict[str, Any]]:
    """The network config of ``models.<model>`` and the training settings of ``train.per_shape.<shape>`` +
    ``train.common`` for it.

    ``train.per_model.<model>`` (e.g. its epochs or learning rate), when set, replaces the shape's
    keys for that model;
    ``train.common.lr``, when set, replaces every shape's learning rate; a ``schedule`` inside the
    model config (a tuned model) overrides all of these and the ``train.common`` keys, being the most
    specific, and its ``per_shape.<shape>`` keys override the rest of the schedule on that shape;
    ``train.protocol`` (:func:`protocol_settings`) overrides all of it for the models it lists.
    The seed derives from the global seed, the shape, the model and (past the first) the replicate,
    so a sweep trial trains what the stage's replicate 0 does.
    """
    from toolpath.models.registry import schedule_for_shape, split_schedule

    common = cfg.train.common
    network, schedule = split_schedule(plain(cfg.models[model]))
    schedule = schedule_for_shape(schedule, shape)
    shared = {"lr": common.lr} if common.get("lr") is not None else {}
    own = plain((cfg.train.get("per_model") or {}).get(model) or {})
    settings = {**plain(cfg.train.per_shape[shape]), **own, **shared, **_common_training(cfg), **schedule,
                **protocol_settings(cfg, model),
                "seed": config.seed_for(cfg.seed, "train", shape, model, *_replicate_key(replicate))}
    return network, settings


def protocol_settings(cfg: DictConfig, model: str) -> dict[str, Any]:
    """``train.protocol.settings``, the model's ``train.protocol.structure`` and ``train.protocol.lr`` for a
    model the protocol lists
    (they win over everything else of :func:`training`); nothing for any other model."""
    protocol = plain(cfg.train.get("protocol") or {})
    if model not in (protocol.get("models") or []):
        return {}
    own = (protocol.get("structure") or {}).get(model) or {}  # the model's structural choice (MCRL's heads)
    return {**(protocol.get("settings") or {}), **own, "lr": protocol["lr"][model]}


def _replicate_key(replicate: int) -> tuple[str, ...]:
    """Replicate 0 keeps the seed the single-run pipeline had; the others add their number."""
    return (f"replicate{replicate}",) if replicate else ()


def _common_training(cfg: DictConfig) -> dict[str, Any]:
    """The ``train.common`` keys every training run shares (threads and class weights go elsewhere)."""
    common = cfg.train.common
    keys = ("patience", "weight_decay", "augment", "aux_loss_weight", "schedule", "warmup", "clip_grad_norm",
            "restore_best", "normalise_inputs")
    return {key: common[key] for key in keys}


def qat_training(cfg: DictConfig, shape: str, model: str):
    """QAT's fine-tuning settings: the model's own training settings (so a shared or tuned learning
    rate carries over) at ``qat.lr_scale`` times the learning rate, for ``qat.epochs`` (or the model's
    ``qat.per_model.<model>.epochs``), its own seed.
    QAT trains without early stopping or auxiliary losses (:func:`toolpath.inference.qat.train_qat`)."""
    from toolpath.models.training.loop import TrainSettings

    _, settings = training(cfg, shape, model)
    own = plain((cfg.qat.get("per_model") or {}).get(model) or {})
    settings.update(lr=settings["lr"] * cfg.qat.lr_scale, epochs=own.get("epochs", cfg.qat.epochs),
                    seed=config.seed_for(cfg.seed, "qat", shape, model))
    return TrainSettings(**settings)


def float_modules(cfg: DictConfig, model: str) -> list[str]:
    """The modules ``qat.float_modules`` keeps in float for ``model`` (none when it lists none)."""
    return [str(name) for name in (plain(cfg.qat).get("float_modules") or {}).get(model) or []]


def all_shapes_training(cfg: DictConfig) -> tuple[dict[str, Any], dict[str, Any]]:
    """The network and settings of the model ``generalise`` trains on every shape at once: its
    ``generalise.schedule`` with the same ``train.common`` keys as every other run."""
    from toolpath.models.registry import split_schedule

    across = cfg.generalise
    network, _ = split_schedule(plain(cfg.models[across.model]))
    settings = {**plain(across.schedule), **_common_training(cfg),
                "seed": config.seed_for(cfg.seed, "generalise", across.model)}
    return network, settings


# ---- smoothing, corners, feedrate ------------------------------------------------------------------
def smoothing(cfg: DictConfig) -> dict[str, Any]:
    """The ``optimize`` section as the smoothing methods take it (NACOA's settings are built from its
    ``nacoa`` node by :func:`toolpath.smoothing.methods.nacoa_settings`, which checks every key)."""
    return plain(cfg.optimize)


def machine(cfg: DictConfig):
    """The machine limits of the feedrate planner (``feedrate.machine``)."""
    return build(cfg.feedrate.machine)


def feed_band(cfg: DictConfig) -> float:
    """``feedrate.band`` (0, the default: point by point; null: the paper's interval rule, one band over a
    whole sensitive run)."""
    return math.inf if cfg.feedrate.band is None else float(cfg.feedrate.band)


def corner(cfg: DictConfig):
    """Corner smoothing settings, PSO's seed from the global seed."""
    from toolpath.corners.path import CornerSettings

    c = plain(cfg.corner)
    return CornerSettings(delta_max=c["delta_max"], min_turn_deg=c["min_turn_deg"], max_leg=c["max_leg"],
                          blend_tolerance=cfg.feedrate.blend_tolerance, curve_samples=c["curve_samples"],
                          line_step=c["line_step"],
                          pso=build(cfg.corner.pso, seed=config.seed_for(cfg.seed, "corner", "pso")))
