"""Classification figures of the report (matplotlib, Agg backend), returned as Figure objects.

The training curves of Figs. 6-7, the confusion matrices per shape, the cross-shape matrix and
Table 5 drawn as curves; :func:`save` writes PNG and PDF without timestamps.  Smoothing figures
are in :mod:`toolpath.reports.smoothing`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from sklearn.metrics import ConfusionMatrixDisplay  # noqa: E402

MCRL_COLOUR = "tab:red"  # the paper draws MCRL red
OTHER_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:pink", "tab:gray",
                 "tab:olive", "tab:cyan")
CORRECT, WRONG = "tab:green", "tab:red"


def save(fig: Figure, stem: Path) -> list[Path]:
    """Write ``stem.png`` and ``stem.pdf`` with no timestamps (same data, same bytes) and close."""
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_suffix(".png"), stem.with_suffix(".pdf")]
    fig.savefig(paths[0], metadata={"Software": None})
    fig.savefig(paths[1], metadata={"CreationDate": None, "Producer": None, "Creator": None})
    plt.close(fig)
    return paths


def confusion_panels(confusions: Mapping[str, np.ndarray], model: str) -> Figure:
    """One confusion matrix per shape, side by side (test split)."""
    fig, axes = plt.subplots(1, len(confusions), figsize=(4 * len(confusions), 3.8), dpi=120, squeeze=False)
    for ax, (shape, confusion) in zip(axes[0], confusions.items(), strict=True):
        ConfusionMatrixDisplay(np.asarray(confusion), display_labels=["1", "2", "3", "4"]).plot(
            ax=ax, colorbar=False, cmap="Blues")
        ax.set_title(f"{model}, {shape} (test)", fontsize=10)
    fig.tight_layout()
    return fig


def curves_figure(curves: Mapping[str, Mapping[str, Sequence[float]]], column: str, label: str) -> Figure:
    """Figs. 6-7: ``column`` (e.g. ``val_accuracy``) against the epoch, every model on one axis per
    shape, MCRL red; one colour per architecture, dashed on the paper's input (``<name>_xy``, Table 3a).
    ``curves``: shape -> model -> the per-epoch CSV as columns."""
    from toolpath.reports.tables import paper_row

    fig, axes = plt.subplots(1, len(curves), figsize=(4.6 * len(curves), 3.6), dpi=120, squeeze=False)
    for ax, (shape, models) in zip(axes[0], curves.items(), strict=True):
        rows = list(dict.fromkeys(paper_row(m) for m in models if paper_row(m) != "mcrl"))
        colour = {row: OTHER_COLOURS[k % len(OTHER_COLOURS)] for k, row in enumerate(rows)} | {"mcrl": MCRL_COLOUR}
        for model, table in models.items():
            is_mcrl = paper_row(model) == "mcrl"
            ax.plot(table["epoch"], table[column], label=model, color=colour[paper_row(model)],
                    linestyle="--" if model != paper_row(model) else "-",
                    linewidth=2.2 if is_mcrl else 1.2, zorder=3 if is_mcrl else 2)
        ax.set_title(shape, fontsize=10)
        ax.set_xlabel("epoch")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0][-1].legend(fontsize=7, loc="best")
    fig.tight_layout()
    return fig


def cross_shape_figure(matrices: Mapping[str, Mapping[str, Mapping[str, Mapping[str, float]]]]) -> Figure:
    """Per model (one panel each): test accuracy when trained on each shape (rows), tested on each (columns)."""
    fig, axes = plt.subplots(1, len(matrices), figsize=(4.6 * len(matrices), 3.9), dpi=120, squeeze=False)
    for ax, (model, matrix) in zip(axes[0], matrices.items(), strict=True):
        shapes = list(matrix)
        values = np.array([[matrix[a][b]["accuracy"] for b in shapes] for a in shapes])
        image = ax.imshow(values, cmap="Blues", vmin=0.0, vmax=1.0)
        for i in range(len(shapes)):
            for j in range(len(shapes)):
                ax.text(j, i, f"{values[i, j]:.3f}", ha="center", va="center",
                        color="white" if values[i, j] > 0.6 else "black", fontsize=9)
        ax.set_xticks(range(len(shapes)), shapes)
        ax.set_yticks(range(len(shapes)), shapes)
        ax.set_xlabel("tested on")
        ax.set_ylabel("trained on")
        ax.set_title(f"{model}: cross-shape test accuracy", fontsize=10)
    fig.colorbar(image, ax=axes[0].tolist(), fraction=0.03)
    return fig


def classification_grid(windows: Mapping[int, np.ndarray], predictions: Mapping[str, Mapping[int, int]]) -> Figure:
    """Table 5 as a figure: rows are models, columns the categories; each cell draws that category's
    window, green where the model predicts its category, red where not (predicted category shown)."""
    models, categories = list(predictions), sorted(windows)
    fig, axes = plt.subplots(len(models), len(categories), figsize=(1.9 * len(categories), 1.25 * len(models)),
                             dpi=120, squeeze=False)
    for r, model in enumerate(models):
        for c, category in enumerate(categories):
            ax, points = axes[r][c], windows[category]
            predicted = predictions[model][category]
            ax.plot(points[:, 0], points[:, 1], color=CORRECT if predicted == category else WRONG, linewidth=1.2)
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_xticks([])
            ax.set_yticks([])
            if predicted != category:
                ax.text(0.98, 0.04, f"-> {predicted}", transform=ax.transAxes, ha="right", fontsize=7, color=WRONG)
            if r == 0:
                ax.set_title(f"category {category}", fontsize=9)
            if c == 0:
                ax.set_ylabel(model, fontsize=8)
    fig.tight_layout()
    return fig
