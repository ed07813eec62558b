"""Generalisation beyond the paper: across shapes, and from synthetic to real G-code."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from toolpath.models.training.metrics import classification_metrics


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


def corpus_report(y: np.ndarray, proba: np.ndarray, arc_share: np.ndarray, arc_threshold: float = 0.5) -> dict:
    """Real G-code windows scored against the exact rule's labels: for all windows, those mostly from
    linearised arcs (``arc_share`` above ``arc_threshold``) and the rest, the count and recall of each
    Table 1 category, how many windows are rough (category 2 or above), accuracy, macro F1 and the
    majority-class accuracy a constant guess would get."""
    y, arcs = np.asarray(y), np.asarray(arc_share) > arc_threshold
    report = {}
    for name, mask in (("all", np.ones(len(y), bool)), ("arcs", arcs), ("lines", ~arcs)):
        if not mask.any():
            report[name] = {"windows": 0}
            continue
        m = classification_metrics(y[mask], proba[mask])
        report[name] = {"windows": int(mask.sum()), "rough_windows": int((y[mask] >= 2).sum()),
                        "accuracy": m["accuracy"], "f1": m["f1"],
                        "majority_accuracy": float(np.bincount(y[mask]).max() / mask.sum()),
                        "per_class": {c: {"count": v["support"], "recall": v["recall"] if v["support"] else None}
                                      for c, v in m["per_class"].items()}}
    return report
