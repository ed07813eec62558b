"""Table 1: the four roughness categories of a window and the LocalCurvature bounds between them.

Apart from the windowing (:mod:`toolpath.geometry.labels.windows`, which reads G-code), so a classifier that only
applies the bounds (the exact rule) does not depend on the G-code reader.
"""

from __future__ import annotations

import numpy as np

__all__ = ["CATEGORY_NAMES", "TABLE1_BOUNDS", "categorize"]

TABLE1_BOUNDS = (1.9, 3.5, 7.6)
CATEGORY_NAMES = ("smooth", "slightly rough", "rugged", "sharp turning corner")


def categorize(curvature: np.ndarray, bounds: tuple[float, float, float] = TABLE1_BOUNDS) -> np.ndarray:
    """Table 1 category (1-4) of each LocalCurvature value."""
    lc = np.asarray(curvature)
    low, mid, high = bounds
    return np.where(lc <= low, 1, np.where(lc < mid, 2, np.where(lc < high, 3, 4))).astype(np.int8)
