"""What the generate stage reports about one shape's windows (DVC and MLflow use these keys: keep them)."""

from __future__ import annotations

import numpy as np

from toolpath.geometry.labels.categories import CATEGORY_NAMES
from toolpath.geometry.labels.split import Split
from toolpath.geometry.labels.windows import Windows

QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


def label_summary(windows: Windows, program: np.ndarray, split: np.ndarray, n_programs: int) -> dict:
    """Class counts and shares, LocalCurvature quantiles, windows and programs per split."""
    counts = np.bincount(windows.label, minlength=5)[1:]
    total = max(int(counts.sum()), 1)
    quantiles = np.quantile(windows.local_curvature, QUANTILES) if len(windows) else [np.nan] * len(QUANTILES)
    return {
        "programs": n_programs,
        "windows": int(len(windows)),
        "unlabelled_points": int(windows.unlabelled_points),
        "class_count": {str(c + 1): int(n) for c, n in enumerate(counts)},
        "class_share": {str(c + 1): round(float(n) / total, 6) for c, n in enumerate(counts)},
        "class_name": {str(c + 1): name for c, name in enumerate(CATEGORY_NAMES)},
        "local_curvature": {f"q{int(q * 100):02d}": round(float(v), 6)
                            for q, v in zip(QUANTILES, quantiles, strict=True)},
        "split_windows": {s.label: int((split == s).sum()) for s in Split},
        "split_programs": {s.label: int(len(np.unique(program[split == s]))) for s in Split},
    }
