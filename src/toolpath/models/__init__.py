"""Window classifiers: MCRL, its seven baselines, the exact LocalCurvature rule, one registry; and how they are
trained and scored (:mod:`~toolpath.models.training`).

The names below load on first use (PEP 562): the training metrics alone (what the report and the product
read) do not import torch.
"""

from importlib import import_module

_HOMES = {**{name: "classic" for name in ("CNN", "LSTM", "MLP", "RNN")},
          **{name: "inputs" for name in ("prepare", "random_reversal", "random_rotation_reflection")},
          "MCRL": "mcrl", **{name: "modern" for name in ("ConvMixer1d", "ConvNeXt1d", "MaxViT1d")},
          "build": "registry", "is_learned": "registry", "LocalCurvatureRule": "rule"}

__all__ = sorted(_HOMES)


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'toolpath.models' has no attribute {name!r}")
    return getattr(import_module(f"toolpath.models.{_HOMES[name]}"), name)
