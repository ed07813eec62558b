"""Smoothing side of the report: Table 6, the curvature reductions of Sec. 5.2.4, Figs. 8-11 and
the reduction / deviation trade-off the paper omits.

Inputs are the ``optimize`` stage's outputs, loaded by the caller: per shape the summary JSON
(``metrics``), the timing JSON (``timing``), the per-window CSV rows (``rows``: dicts of strings)
and the smoothed windows (``smoothed``: arrays ``points``, ``window``, ``method``, ``mode``,
``encoding``) beside the original windows.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from toolpath.geometry.curvature import local_curvature, reduction_pct  # noqa: E402
from toolpath.reports.paper import PAPER_REDUCTION  # noqa: E402
from toolpath.reports.smoothing_tables import MODE_LABEL, label  # noqa: E402
from toolpath.reports.tables import Table  # noqa: E402

PAPER_METHODS = ("mean_filter", "bezier", "nacoa")
Y_FLOOR = -50.0  # lowest reduction drawn in the trade-off figure (per cent)  # Figs. 9-11 and Sec. 5.2.4
MODES = ("none", "tube", "bound")


def reduction_table(metrics: Mapping[str, Mapping]) -> Table:
    """The former headline, under its own name: mean LocalCurvature reduction of mean filter, Bezier and
    NACOA over every sampled window (categories 1-4), per shape and fidelity mode, with the max deviation."""
    headers = ["shape", "mode", "windows", *(f"{label(m)} % (paper)" for m in PAPER_METHODS),
               *(f"{label(m)} max two-sided dev. mm" for m in PAPER_METHODS)]
    table = Table("All-category curvature reduction of the paper's three methods (every sampled window, category 1 "
                  "included; the paper's metric is the table above)", headers)
    for shape, m in metrics.items():
        for mode in MODES:
            stats = m["methods"].get(mode, {}).get("plain", {})
            if not stats:
                continue
            cells: list[object] = [shape, MODE_LABEL[mode],
                                   stats[PAPER_METHODS[-1]]["windows"]]
            for method in PAPER_METHODS:
                ours = stats[method]["mean_reduction_pct"]
                cells.append(f"{ours:.1f} ({PAPER_REDUCTION[method]:.0f}, {ours - PAPER_REDUCTION[method]:+.1f})")
            cells += [f"{stats[method]['max_hausdorff_mm']:.3f}" for method in PAPER_METHODS]
            table.add(cells)
    table.notes.append("Mean over the seeded sample of test windows, every Table 1 category equally represented "
                       "(Sec. 5.3 never smooths category 1, where a method can raise LocalCurvature while lowering "
                       "Fitness). The paper reports the reduction only, never the deviation it costs.")
    table.notes += ranking_notes(metrics)
    return table


def ranking_notes(metrics: Mapping[str, Mapping]) -> list[str]:
    """Per shape and mode, our ranking of the paper's three methods by mean reduction, and whether it is
    the paper's (NACOA > Bezier > mean filter)."""
    paper = sorted(PAPER_METHODS, key=lambda m: -PAPER_REDUCTION[m])
    notes = []
    for shape, m in metrics.items():
        for mode in MODES:
            stats = m["methods"].get(mode, {}).get("plain", {})
            if not all(k in stats for k in PAPER_METHODS):
                continue
            ours = sorted(PAPER_METHODS, key=lambda k: -stats[k]["mean_reduction_pct"])
            verdict = "as in the paper" if ours == paper else f"not the paper's {' > '.join(map(label, paper))}"
            notes.append(f"{shape}, {MODE_LABEL[mode]}, all categories, no interval: "
                         f"{' > '.join(map(label, ours))} ({verdict}).")
    return notes


def _smoothed(smoothed: Mapping[str, np.ndarray], window: int, method: str, mode: str) -> np.ndarray | None:
    hit = np.flatnonzero((smoothed["window"] == window) & (smoothed["method"] == method)
                         & (smoothed["mode"] == mode) & (smoothed["encoding"] == "plain"))
    return smoothed["points"][hit[0]].astype(np.float64) if len(hit) else None


def methods_figure(cases: Mapping[str, tuple[np.ndarray, Mapping[str, np.ndarray]]], mode: str) -> Figure:
    """Fig. 8: one window per shape, the original and every method's result.  ``cases``: shape ->
    (original window, method -> smoothed window)."""
    fig, axes = plt.subplots(1, len(cases), figsize=(5.2 * len(cases), 4.4), dpi=120, squeeze=False)
    for ax, (shape, (original, results)) in zip(axes[0], cases.items(), strict=True):
        ax.plot(original[:, 0], original[:, 1], color="black", linewidth=2.4, label="original", zorder=1)
        for method, points in results.items():
            is_nacoa = method == "nacoa"
            ax.plot(points[:, 0], points[:, 1], linewidth=1.8 if is_nacoa else 1.0, label=label(method),
                    color="tab:red" if is_nacoa else None, zorder=3 if is_nacoa else 2)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(f"{shape} (mode: {mode})", fontsize=10)
        ax.tick_params(labelsize=7)
    axes[0][-1].legend(fontsize=7, loc="best")
    fig.tight_layout()
    return fig


def before_after_figure(shape: str, original: np.ndarray, results: Mapping[str, np.ndarray],
                        mean_reduction: Mapping[str, float], mode: str) -> Figure:
    """Figs. 9-11: mean filter, Bezier and NACOA on one window of ``shape``, each before / after with
    this window's curvature reduction and the mean over the sample in the title."""
    fig, axes = plt.subplots(1, len(results), figsize=(4.6 * len(results), 4.0), dpi=120, squeeze=False)
    before = float(local_curvature(original))
    for ax, (method, points) in zip(axes[0], results.items(), strict=True):
        after = float(local_curvature(points))
        ax.plot(original[:, 0], original[:, 1], color="tab:gray", linewidth=1.0, label="before")
        ax.plot(points[:, 0], points[:, 1], color="tab:red", linewidth=1.5, label="after")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(f"{label(method)}: -{reduction_pct(before, after):.0f} % here\n"
                     f"(mean {mean_reduction[method]:.0f} %, paper {PAPER_REDUCTION[method]:.0f} %)", fontsize=9)
        ax.tick_params(labelsize=7)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(f"{shape}: LocalCurvature {before:.2f} before (mode: {mode})", fontsize=10)
    fig.tight_layout()
    return fig


def notice_figure(text: str) -> Figure:
    """A figure that says why its drawing is absent: the file DVC declares still exists and says so."""
    fig = plt.figure(figsize=(6.0, 1.2), dpi=120)
    fig.text(0.5, 0.5, text, ha="center", va="center", fontsize=9, wrap=True)
    return fig


def tradeoff_figure(rows: Mapping[str, Sequence[Mapping[str, str]]]) -> Figure:
    """Ours: curvature reduction against the two-sided distance from the original, per method and
    mode (small dots per window, a large marker for the mean), pooled over shapes."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), dpi=120, sharey=True)
    for ax, mode in zip(axes, ("none", "bound"), strict=True):
        by_method: dict[str, list[tuple[float, float]]] = {}
        for shape_rows in rows.values():
            for r in shape_rows:
                if r["mode"] == mode and r["encoding"] == "plain":
                    by_method.setdefault(r["method"], []).append((float(r["hausdorff_mm"]),
                                                                  float(r["reduction_pct"])))
        for method, points in sorted(by_method.items()):
            xy = np.array(points)
            dots = ax.scatter(xy[:, 0], xy[:, 1], s=5, alpha=0.25)
            ax.scatter(xy[:, 0].mean(), xy[:, 1].mean(), s=70, color=dots.get_facecolor()[0][:3],
                       edgecolor="black", label=label(method), zorder=3)
        below = sum(int((np.array(v)[:, 1] < Y_FLOOR).sum()) for v in by_method.values())
        if below:  # a few windows made worse by far (the permuting start) would flatten everything else
            ax.text(0.02, 0.03, f"{below} windows below {Y_FLOOR:.0f} % not shown", transform=ax.transAxes, fontsize=7)
        ax.set_ylim(Y_FLOOR, 105)
        ax.set_xscale("symlog", linthresh=0.01)
        ax.set_xlabel("two-sided deviation from the original (mm)")
        ax.set_title("paper mode (no bound)" if mode == "none" else "bound mode", fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("LocalCurvature reduction (%)")
    axes[1].legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return fig


def pick_window(rows: Sequence[Mapping[str, str]], category: int, head_to_head: bool,
                seed: int) -> tuple[int, int] | None:
    """A seeded choice ``(window, its category)`` among the sampled windows of ``category`` (those every
    method ran when ``head_to_head``), so the figures show a drawn window, not a chosen one.  When the
    sample has none of ``category`` (or no baseline ran) the draw is from every eligible window; the
    category returned says which, and the captions print it."""
    eligible = [r for r in rows if not head_to_head or r["baseline_window"] == "True"] or list(rows)
    of_category = [r for r in eligible if int(r["category"]) == category] or eligible
    pool = sorted({(int(r["window"]), int(r["category"])) for r in of_category})
    if not pool:
        return None
    return pool[int(np.random.default_rng(seed).integers(len(pool)))]


def window_results(smoothed: Mapping[str, np.ndarray], window: int, methods: Sequence[str],
                   mode: str) -> dict[str, np.ndarray]:
    """Each method's smoothed version of ``window`` in ``mode`` (plain encoding), where it ran."""
    results = {m: _smoothed(smoothed, window, m, mode) for m in methods}
    return {m: p for m, p in results.items() if p is not None}
