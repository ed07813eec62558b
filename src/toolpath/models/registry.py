"""Models by config: ``conf/model/<name>.yaml`` holds ``_target_`` and arguments; :func:`build` instantiates.

The list of models is conf/'s (``models`` and ``train.models``); this module names none of them."""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence
from typing import Any


def split_schedule(config: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """A model config without its optional ``schedule`` (training settings that a tuned model, e.g.
    ``conf/model/mcrl_tuned.yaml`` written by ``python -m toolpath.sweep``, carries with it), and that
    schedule; the schedule overrides the shape's ``train.per_shape.<shape>`` keys for this model only."""
    network = dict(config)
    return network, dict(network.pop("schedule", None) or {})


def schedule_for_shape(schedule: Mapping[str, Any], shape: str) -> dict[str, Any]:
    """A model's schedule on one shape: its keys, with those of its ``per_shape.<shape>`` (e.g. a shape
    whose training is still improving at the common epoch count) over them."""
    own = dict(schedule)
    per_shape = own.pop("per_shape", None) or {}
    return {**own, **dict(per_shape.get(shape) or {})}


def _plain(value: Any) -> Any:
    """Config containers (OmegaConf's included) as plain dicts and lists, as the constructors expect."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, Sequence) and not isinstance(value, str):
        return [_plain(v) for v in value]
    return value


def parameter_count(model) -> int:
    """Trainable parameters of a torch network (0 for the rule)."""
    params = getattr(model, "parameters", None)
    return sum(p.numel() for p in params() if p.requires_grad) if params else 0


def target_class(config: Mapping[str, Any]) -> type:
    """The class a model config's ``_target_`` names."""
    target = config.get("_target_")
    if not isinstance(target, str) or "." not in target:
        raise ValueError(f"a model config needs a `_target_` naming its class, got {target!r}")
    module, _, name = target.rpartition(".")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"model `_target_` {target!r} does not name a class: {exc}") from None


def is_learned(config: Mapping[str, Any]) -> bool:
    """Whether a model config names a torch network (trained) rather than a fixed rule."""
    import torch

    return issubclass(target_class(config), torch.nn.Module)


def build(config: Mapping[str, Any]) -> Any:
    """Instantiate a model from a flat config: ``_target_`` (a dotted class path) and its arguments.

    A few lines instead of Hydra's ``instantiate``, so the domain packages do not depend on Hydra;
    every ``conf/model`` file is one flat ``_target_`` with plain arguments (tested).  A tuned model's
    ``schedule`` is training settings, not an argument: it is left out."""
    arguments, _ = split_schedule(_plain(config))
    cls = target_class(arguments)
    arguments.pop("_target_")
    return cls(**arguments)
