"""The exact LocalCurvature rule (Eq. 3 + Table 1) as a classifier: the ceiling every learned model
is compared with, and its speed the floor."""

from __future__ import annotations

import numpy as np
from sklearn.base import BaseEstimator, ClassifierMixin

from toolpath.geometry.curvature import local_curvature
from toolpath.geometry.labels.categories import TABLE1_BOUNDS, categorize

CLASSES = np.array([1, 2, 3, 4])


def as_windows(X) -> np.ndarray:
    """(N, n, 2) float64 windows from (N, n, 2) or flattened (N, 2n) input."""
    X = np.asarray(X, dtype=np.float64)
    if X.ndim == 2 and X.shape[1] % 2 == 0:
        X = X.reshape(len(X), -1, 2)
    if X.ndim != 3 or X.shape[2] != 2 or X.shape[1] < 3:
        raise ValueError(f"expected windows of shape (N, n, 2) with n >= 3, got {X.shape}")
    return X


class LocalCurvatureRule(ClassifierMixin, BaseEstimator):
    """Predicts the Table 1 category of each window from its LocalCurvature; ``fit`` learns nothing.

    Parameters
    ----------
    bounds : the three Table 1 thresholds (1.9, 3.5, 7.6).
    """

    def __init__(self, bounds: tuple[float, float, float] = TABLE1_BOUNDS) -> None:
        self.bounds = bounds

    def fit(self, X, y=None):
        X = as_windows(X)
        self.classes_ = CLASSES.copy()
        self.n_points_ = X.shape[1]
        return self

    def decision_function(self, X) -> np.ndarray:
        """LocalCurvature of each window (Eq. 3)."""
        return local_curvature(as_windows(X))

    def predict(self, X) -> np.ndarray:
        return categorize(self.decision_function(X), tuple(self.bounds)).astype(np.int64)

    def predict_proba(self, X) -> np.ndarray:
        """One-hot probabilities of the predicted category."""
        pred = self.predict(X)
        return (pred[:, None] == self.classes_[None, :]).astype(np.float64)
