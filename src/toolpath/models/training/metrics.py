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



def _accuracy_f1(confusion: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Accuracy and macro F1 (Eq. 28, 32) of confusion matrices ``(..., k, k)`` (rows true, columns
    predicted); the macro average runs over the classes present (true or predicted), as scikit-learn's."""
    tp = np.diagonal(confusion, axis1=-2, axis2=-1)
    true, pred = confusion.sum(axis=-1), confusion.sum(axis=-2)
    total = np.maximum(true.sum(axis=-1), 1.0)
    f1 = np.where(true + pred > 0, 2 * tp / np.maximum(true + pred, 1e-12), 0.0)
    present = (true + pred) > 0
    return tp.sum(axis=-1) / total, (f1 * present).sum(axis=-1) / np.maximum(present.sum(axis=-1), 1)


def _confusions(predicted: np.ndarray, y: np.ndarray, index: np.ndarray, programs: int) -> np.ndarray:
    """(seeds, programs, k, k) confusion counts of per-seed predictions ``(seeds, n)``."""
    k = len(CLASSES)
    true = np.searchsorted(CLASSES, y)
    cells = index * k * k + true * k
    out = np.zeros((len(predicted), programs * k * k))
    for s, p in enumerate(predicted):
        out[s] = np.bincount(cells + np.searchsorted(CLASSES, p), minlength=programs * k * k)
    return out.reshape(len(predicted), programs, k, k)


def paired_bootstrap(predicted_a: np.ndarray, predicted_b: np.ndarray, y: np.ndarray, programs: np.ndarray,
                     seed: int, draws: int = 2000, level: float = 0.95) -> dict:
    """Model A minus model B in accuracy and macro F1 on the same test windows, with a percentile
    bootstrap interval that resamples test programs and training seeds together.

    ``predicted_a`` / ``predicted_b``: (seeds, windows) predicted categories of each model's replicates.
    Each draw takes the programs with replacement (the same programs for both models: paired) and,
    per model, its seeds with replacement; a model's figure is the mean over its drawn seeds of the
    metric on the drawn programs.  The point estimate is the difference of the seed means on all
    programs.  ``verdict``: "better" when the interval lies above 0, "worse" below, else "no difference
    shown"."""
    ids, index = np.unique(np.asarray(programs), return_inverse=True)
    rng = np.random.default_rng(seed)
    weights = np.stack([np.bincount(row, minlength=len(ids)) for row in rng.integers(0, len(ids), (draws, len(ids)))])
    figures = []
    for predicted in (np.atleast_2d(predicted_a), np.atleast_2d(predicted_b)):
        counts = _confusions(predicted, np.asarray(y), index, len(ids))
        drawn = np.einsum("dp,spij->dsij", weights.astype(float), counts)  # (draws, seeds, k, k)
        pick = rng.integers(0, len(predicted), (draws, len(predicted)))
        per_seed = _accuracy_f1(drawn)
        full = _accuracy_f1(counts.sum(axis=1))
        figures.append([(np.take_along_axis(m, pick, axis=1).mean(axis=1), float(f.mean()))
                        for m, f in zip(per_seed, full, strict=True)])
    out = {}
    for k, name in enumerate(("accuracy", "f1")):
        (boot_a, point_a), (boot_b, point_b) = figures[0][k], figures[1][k]
        low, high = np.quantile(boot_a - boot_b, [(1 - level) / 2, (1 + level) / 2])
        verdict = "better" if low > 0 else "worse" if high < 0 else "no difference shown"
        out[name] = {"difference": point_a - point_b, "low": float(low), "high": float(high), "verdict": verdict}
    out.update(programs=int(len(ids)), seeds=[int(len(np.atleast_2d(p))) for p in (predicted_a, predicted_b)],
               level=level, draws=draws)
    return out
