"""Models by name: ``conf/model/<name>.yaml`` holds ``_target_`` and arguments; :func:`build` instantiates."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from hydra.utils import instantiate

#: The nine model names of Table 3 (plus the exact rule) and the class each config targets.
MODEL_NAMES = ("mcrl", "mlp", "cnn", "rnn", "lstm", "convmixer", "convnext", "maxvit", "rule")
LEARNED = MODEL_NAMES[:-1]


def build(config: Mapping[str, Any]) -> Any:
    """Instantiate a model from a config with ``_target_`` (lists become tuples for sizes)."""
    return instantiate(dict(config), _convert_="all")
