"""A scikit-learn classifier around any torch network of the registry.

``TorchClassifier(network={"_target_": "toolpath.models.MCRL", ...})``: ``fit`` builds a fresh
network from that config with a seeded initialisation and trains it; ``predict_proba`` is the
softmax of its logits.  Labels are the Table 1 categories 1-4 (``classes_``), so scikit-learn's
metrics work unchanged on every model, the exact rule included.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import torch
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.class_weight import compute_class_weight

from toolpath.models.registry import build, target_class
from toolpath.models.rule import CLASSES, as_windows
from toolpath.models.training.loop import TrainSettings, fit_network, predict_logits


class TorchClassifier(ClassifierMixin, BaseEstimator):
    """Fit / predict / predict_proba around a network config (``_target_`` and its arguments).

    Parameters
    ----------
    network : mapping with ``_target_`` (a class of :mod:`toolpath.models`) and constructor args.
    settings : mapping of :class:`~toolpath.models.training.TrainSettings` fields.
    class_weight : ``None`` or ``"balanced"`` (inverse class frequency in the training labels).
    """

    def __init__(self, network: Mapping[str, Any] | None = None, settings: Mapping[str, Any] | None = None,
                 class_weight: str | None = None) -> None:
        self.network = network
        self.settings = settings
        self.class_weight = class_weight

    def _settings(self) -> TrainSettings:
        return TrainSettings(**dict(self.settings or {}))

    def fit(self, X, y, X_val=None, y_val=None, on_epoch=None):
        X = as_windows(X).astype(np.float32)
        index = np.searchsorted(CLASSES, np.asarray(y))
        settings = self._settings()
        torch.manual_seed(settings.seed)  # the network's initial weights
        self.network_ = build(dict(self.network or {"_target_": "toolpath.models.MCRL"}))
        weight = None
        if self.class_weight == "balanced":
            present = np.unique(index)
            weight = np.ones(len(CLASSES))
            weight[present] = compute_class_weight("balanced", classes=present, y=index)
        val = (as_windows(X_val).astype(np.float32), np.searchsorted(CLASSES, np.asarray(y_val))) \
            if X_val is not None else (None, None)
        self.history_ = fit_network(self.network_, X, index, settings, *val, class_weight=weight, on_epoch=on_epoch)
        self.classes_ = CLASSES.copy()
        return self

    def decision_function(self, X) -> np.ndarray:
        """Logits, (N, 4)."""
        X = torch.as_tensor(as_windows(X), dtype=torch.float32)
        return predict_logits(self.network_, X).numpy().astype(np.float64)

    def predict_proba(self, X) -> np.ndarray:
        logits = self.decision_function(X)
        e = np.exp(logits - logits.max(axis=1, keepdims=True))
        return e / e.sum(axis=1, keepdims=True)

    def predict(self, X) -> np.ndarray:
        return self.classes_[self.decision_function(X).argmax(axis=1)]


def to_checkpoint(model: Any) -> dict:
    """A plain dict (config, weights, history) that ``torch.load(weights_only=True)`` can read."""
    if isinstance(model, TorchClassifier):
        return {"kind": "torch", "network": dict(model.network), "settings": dict(model.settings or {}),
                "state_dict": model.network_.state_dict(),
                "history": [vars(r) for r in model.history_]}
    return {"kind": "rule", "network": {"_target_": "toolpath.models.LocalCurvatureRule",
                                        "bounds": list(model.bounds)}}


def from_checkpoint(checkpoint: Mapping[str, Any]) -> Any:
    """The fitted classifier a checkpoint describes (eval mode, ready to predict)."""
    if checkpoint["kind"] == "rule":
        rule = build(checkpoint["network"])
        rule.classes_ = CLASSES.copy()
        return rule
    clf = TorchClassifier(network=checkpoint["network"], settings=checkpoint["settings"])
    clf.network_ = build(checkpoint["network"])
    clf.network_.load_state_dict(checkpoint["state_dict"])
    clf.network_.eval()
    clf.classes_ = CLASSES.copy()
    clf.history_ = []
    return clf


def fit_and_score(network: Mapping[str, Any], settings: Mapping[str, Any], class_weight: str | None,
                  parts: Mapping[str, tuple[np.ndarray, np.ndarray]], on_epoch=None,
                  programs: Mapping[str, np.ndarray] | None = None) -> tuple[Any, dict, list, float]:
    """Train one model on ``parts['train']`` (validation: ``parts['val']``) and score it on the
    validation and test splits (those ``parts`` holds): (classifier, metrics, per-epoch history,
    seconds).  The exact rule (an estimator that is no torch module) is fitted as it is; it learns
    nothing.  The train stage and every sweep trial call this, so a trial trains what the stage
    would.  With ``programs`` (each split's program per window) each split's accuracy gets a
    bootstrap interval over its programs."""
    import time

    from toolpath.models.training.metrics import classification_metrics, program_bootstrap

    started = time.perf_counter()
    if issubclass(target_class(network), torch.nn.Module):
        clf = TorchClassifier(network, settings, class_weight).fit(*parts["train"], *parts["val"], on_epoch=on_epoch)
        history = clf.history_
    else:
        clf, history = build(network).fit(parts["train"][0]), []
    seconds = time.perf_counter() - started
    metrics = {}
    for split in (s for s in ("val", "test") if s in parts):  # a tuning run is given no test split
        proba = clf.predict_proba(parts[split][0])
        metrics[split] = classification_metrics(parts[split][1], proba)
        if programs is not None:
            correct = clf.classes_[proba.argmax(axis=1)] == parts[split][1]
            metrics[split]["accuracy_ci"] = program_bootstrap(correct, programs[split], settings.get("seed", 0))
    metrics["epochs_run"] = len(history)
    return clf, metrics, history, seconds
