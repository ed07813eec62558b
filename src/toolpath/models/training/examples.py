"""Table 5 of Li et al.: one seeded random test window per category, and each model's prediction for it."""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np


def draw_per_category(windows: np.ndarray, labels: np.ndarray, test: np.ndarray, categories: tuple[int, ...],
                      seed: int) -> dict[int, np.ndarray]:
    """One window of each category drawn at random from the test windows (``test`` a boolean mask), in
    category order; a category with no test window is left out."""
    rng = np.random.default_rng(seed)
    drawn = {}
    for category in categories:
        pool = np.flatnonzero((labels == category) & test)
        if len(pool):
            drawn[int(category)] = windows[rng.choice(pool)]
    return drawn


def predictions(drawn: Mapping[int, np.ndarray], predictors: Mapping[str, Callable[[np.ndarray], np.ndarray]]
                ) -> dict[str, dict[int, int]]:
    """Each model's predicted category for every drawn window: ``{model: {true category: predicted}}``."""
    batch = np.stack(list(drawn.values()))
    return {model: {c: int(p) for c, p in zip(drawn, predict(batch), strict=True)}
            for model, predict in predictors.items()}
