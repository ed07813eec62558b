"""A logistic-regression reference on each input (Table 3's "what the input alone gives").

Multinomial logistic regression (scikit-learn, L-BFGS) on the flattened per-window input the networks
see before their first learned layer: the turning terms (1 - cos, sin) of Eq. 1-3, or the window's
similarity-normalised coordinates (:func:`toolpath.models.inputs.prepare`), standardised per
feature on the training windows.  On turning terms a linear function of the input is LocalCurvature
itself (Eq. 3 sums the first channel), so this row shows how much of Table 3b the input alone explains;
on coordinates it shows what a model without learned layers finds.
"""

from __future__ import annotations

import numpy as np
import torch
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import Pipeline, make_pipeline
from sklearn.preprocessing import StandardScaler

from toolpath.models.inputs import INPUTS, prepare, turning_features


def features(windows: np.ndarray, inputs: str) -> np.ndarray:
    """(N, 2n) flattened input of (N, n, 2) windows (float64)."""
    if inputs not in INPUTS:
        raise ValueError(f"inputs must be one of {INPUTS}, got {inputs!r}")
    x = torch.as_tensor(np.asarray(windows), dtype=torch.float64)
    out = turning_features(x) if inputs == "turning" else prepare(x)
    return out.flatten(1).numpy()


def fit_logistic(windows: np.ndarray, labels: np.ndarray, inputs: str, max_iter: int = 2000) -> Pipeline:
    """Standardise, then multinomial logistic regression (deterministic: L-BFGS, no random draw)."""
    model = make_pipeline(StandardScaler(), LogisticRegression(max_iter=max_iter))
    return model.fit(features(windows, inputs), np.asarray(labels))


def probabilities(model: Pipeline, windows: np.ndarray, inputs: str, classes: np.ndarray) -> np.ndarray:
    """(N, len(classes)) probabilities, zero for a class the training windows never held."""
    out = np.zeros((len(windows), len(classes)))
    out[:, np.searchsorted(classes, model.classes_)] = model.predict_proba(features(windows, inputs))
    return out
