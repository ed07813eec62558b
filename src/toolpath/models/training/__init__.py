"""Training and evaluation of the window classifiers: the loop (:mod:`~toolpath.models.training.loop`), the
scikit-learn estimator around it (:mod:`~toolpath.models.training.classifier`), Table 3's metrics
(:mod:`~toolpath.models.training.metrics`), seeds and intervals (:mod:`~toolpath.models.training.replicates`),
generalisation (:mod:`~toolpath.models.training.generalise`) and Table 5's drawn windows
(:mod:`~toolpath.models.training.examples`).

The names below load on first use (PEP 562): the metrics alone (what the report reads) do not import torch.
"""

from importlib import import_module

_HOMES = {"TorchClassifier": "classifier", **{name: "loop" for name in (
    "EpochRecord", "TrainSettings", "fit_network", "predict_logits")}}

__all__ = sorted(_HOMES)


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'toolpath.models.training' has no attribute {name!r}")
    return getattr(import_module(f"toolpath.models.training.{_HOMES[name]}"), name)
