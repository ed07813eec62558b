"""Models by name: ``conf/model/<name>.yaml`` holds ``_target_`` and arguments; :func:`build` instantiates."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from hydra.utils import instantiate

#: The nine model names of Table 3 (plus the exact rule) and the class each config targets.
MODEL_NAMES = ("mcrl", "mlp", "cnn", "rnn", "lstm", "convmixer", "convnext", "maxvit", "rule")
LEARNED = MODEL_NAMES[:-1]


def split_schedule(config: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """A model config without its optional ``schedule`` (training settings that a tuned model, e.g.
    ``conf/model/mcrl_tuned.yaml`` written by ``python -m toolpath.sweep``, carries with it), and that
    schedule; the schedule overrides the shape's ``train.<shape>`` keys for this model only."""
    network = dict(config)
    return network, dict(network.pop("schedule", None) or {})


def build(config: Mapping[str, Any]) -> Any:
    """Instantiate a model from a config with ``_target_`` (lists become tuples for sizes)."""
    return instantiate(dict(config), _convert_="all")
