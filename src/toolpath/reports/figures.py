"""Figures (matplotlib, Agg backend) returned as Figure objects; callers save or log them."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from sklearn.metrics import ConfusionMatrixDisplay  # noqa: E402


def confusion_figure(confusion: list[list[int]] | np.ndarray, title: str) -> Figure:
    """Confusion matrix of the four Table 1 categories (rows: true, columns: predicted)."""
    fig, ax = plt.subplots(figsize=(4.2, 3.8), dpi=120)
    ConfusionMatrixDisplay(np.asarray(confusion), display_labels=["1", "2", "3", "4"]).plot(
        ax=ax, colorbar=False, cmap="Blues")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    return fig
