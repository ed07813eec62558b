"""Table 3's metrics (Eq. 28-33) from scikit-learn, on held-out windows.

Macro averages run over the four Table 1 categories.  AUC is one-vs-rest per category and
macro-averaged over the categories present in ``y_true`` (a category with no positive window has
no ROC curve); the per-class AUC of an absent category is reported as null.
"""

from __future__ import annotations

import numpy as np
from sklearn.metrics import (
    accuracy_score,
    confusion_matrix,
    log_loss,
    precision_recall_fscore_support,
    roc_auc_score,
)

CLASSES = np.array([1, 2, 3, 4])
_EPS = 1e-7  # probabilities are clipped so a one-hot rule gets a finite (large) loss


def classification_metrics(y_true: np.ndarray, proba: np.ndarray, classes: np.ndarray = CLASSES) -> dict:
    """Accuracy, cross-entropy, macro precision / recall / F1, macro AUC, per-class figures, confusion.

    Parameters
    ----------
    y_true : (N,) labels from ``classes``.
    proba : (N, len(classes)) predicted probabilities (rows sum to 1).
    """
    y_true = np.asarray(y_true)
    proba = np.clip(np.asarray(proba, dtype=np.float64), _EPS, 1.0)
    proba = proba / proba.sum(axis=1, keepdims=True)
    pred = classes[proba.argmax(axis=1)]
    precision, recall, f1, support = precision_recall_fscore_support(
        y_true, pred, labels=classes, average=None, zero_division=0)
    macro = precision_recall_fscore_support(y_true, pred, labels=classes, average="macro", zero_division=0)
    auc_per_class = {}
    for k, c in enumerate(classes):
        positive = y_true == c
        auc_per_class[str(c)] = (float(roc_auc_score(positive, proba[:, k]))
                                 if 0 < positive.sum() < len(y_true) else None)
    present = [v for v in auc_per_class.values() if v is not None]
    return {
        "accuracy": float(accuracy_score(y_true, pred)),
        "loss": float(log_loss(y_true, proba, labels=classes)),
        "precision": float(macro[0]),
        "recall": float(macro[1]),
        "f1": float(macro[2]),
        "auc": float(np.mean(present)) if present else None,
        "windows": int(len(y_true)),
        "per_class": {str(c): {"precision": float(precision[k]), "recall": float(recall[k]), "f1": float(f1[k]),
                               "auc": auc_per_class[str(c)], "support": int(support[k])}
                      for k, c in enumerate(classes)},
        "confusion": confusion_matrix(y_true, pred, labels=classes).tolist(),
    }


DEGENERATE = "degenerate (majority class)"


def degenerate(metrics: dict) -> bool:
    """True when every prediction of a split fell into one class (the confusion matrix has one non-empty
    column): such a model has learned nothing, and its accuracy is the share of that class, so it is
    shown as :data:`DEGENERATE`, never as a score.  Without a confusion matrix there is nothing to judge
    (False)."""
    if metrics.get("confusion") is None:
        return False
    columns = np.asarray(metrics["confusion"]).sum(axis=0)
    return int((columns > 0).sum()) <= 1 and int(columns.sum()) > 0


def program_bootstrap(correct: np.ndarray, programs: np.ndarray, seed: int, draws: int = 2000,
                      level: float = 0.95) -> dict:
    """A percentile bootstrap interval of the accuracy over *programs*, the independent unit (windows of
    one program are not independent): programs are drawn with replacement, each draw's accuracy is the
    share of correct windows in the drawn programs.  Returns the interval, its half-width and the
    number of programs."""
    correct = np.asarray(correct, dtype=np.float64)
    ids, index = np.unique(np.asarray(programs), return_inverse=True)
    hits = np.bincount(index, weights=correct, minlength=len(ids))
    sizes = np.bincount(index, minlength=len(ids)).astype(np.float64)
    rng = np.random.default_rng(seed)
    pick = rng.integers(0, len(ids), size=(draws, len(ids)))
    accuracy = hits[pick].sum(axis=1) / np.maximum(sizes[pick].sum(axis=1), 1.0)
    low, high = np.quantile(accuracy, [(1 - level) / 2, (1 + level) / 2])
    return {"low": float(low), "high": float(high), "half_width": float((high - low) / 2), "programs": int(len(ids)),
            "level": level}

