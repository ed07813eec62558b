"""Generalisation beyond the paper: across shapes, and from synthetic to real G-code."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from toolpath.training.metrics import classification_metrics


def best_by_validation(val_accuracy: Mapping[str, float]) -> str:
    """The model with the highest validation accuracy (ties: the first name in sorted order)."""
    return max(sorted(val_accuracy), key=lambda name: val_accuracy[name])


def cross_shape_matrix(classifiers: Mapping[str, Any], test_sets: Mapping[str, tuple[np.ndarray, np.ndarray]]
                       ) -> dict[str, dict[str, dict[str, float]]]:
    """``matrix[trained_on][tested_on]`` = accuracy and macro F1 on the test split of ``tested_on``."""
    matrix: dict[str, dict[str, dict[str, float]]] = {}
    for trained_on, clf in classifiers.items():
        matrix[trained_on] = {}
        for tested_on, (X, y) in test_sets.items():
            m = classification_metrics(y, clf.predict_proba(X))
            matrix[trained_on][tested_on] = {"accuracy": m["accuracy"], "f1": m["f1"]}
    return matrix
