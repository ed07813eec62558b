"""A ranking of every network across the three shapes (issue 39): autorank's Friedman test with the
Nemenyi post-hoc test and its critical-difference figure.

The repeated measures are the (shape, seed) blocks: each network's test accuracy on one shape with its
replicate-``r`` seed.  Seeds of different networks do not share initialisation or data order, so the
seed is a further draw within the shape, not a pairing; the figure says which differences in mean rank
exceed the critical difference.  A network with a degenerate seed (one class predicted) is left out
and named: it is never scored.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from toolpath.reports.tables import Table


def accuracy_blocks(metrics: Mapping[str, Mapping[str, Mapping]], models: Sequence[str]) -> tuple[dict, list[str]]:
    """({model: [test accuracy per (shape, seed) block]}, networks left out as degenerate); only blocks
    every kept network has."""
    kept, dropped = {}, []
    for model in models:
        per_shape = [metrics[s][model]["replicates"] for s in metrics if model in metrics[s]]
        if any(r["degenerate"] for r in per_shape):
            dropped.append(model)
            continue
        kept[model] = {(shape, seed): value for shape in metrics if model in metrics[shape]
                       for seed, value in metrics[shape][model]["replicates"]["test"]["accuracy"]["per_seed"].items()}
    common = set.intersection(*(set(v) for v in kept.values())) if kept else set()
    blocks = sorted(common)
    return {m: [v[b] for b in blocks] for m, v in kept.items()}, dropped


def rank(blocks: Mapping[str, Sequence[float]], alpha: float = 0.05):
    """autorank's non-parametric path (Friedman, Nemenyi): its result, or None with fewer than 2 networks
    or 5 blocks (too few for the test)."""
    import contextlib
    import io

    import pandas as pd
    from autorank import autorank

    if len(blocks) < 2 or len(next(iter(blocks.values()))) < 5:
        return None
    frame = pd.DataFrame({m: np.asarray(v, dtype=float) for m, v in blocks.items()})
    with contextlib.redirect_stdout(io.StringIO()):  # autorank prints its choice of test even when not verbose
        return autorank(frame, alpha=alpha, verbose=False, force_mode="nonparametric")


def ranking_table(result, blocks: Mapping[str, Sequence[float]], dropped: Sequence[str]) -> Table:
    """Mean rank (1 = best), median accuracy and the networks the test cannot tell apart from each; with
    no ``result`` (too few networks or blocks) the table says so."""
    count = len(next(iter(blocks.values()))) if blocks else 0
    table = Table(f"Table 3d: every network ranked by test accuracy over {count} (shape, seed) blocks "
                  "(Friedman test, Nemenyi post-hoc)", ["network", "mean rank", "median accuracy %",
                                                        "not shown different from"])
    left_out = f" Left out as degenerate: {', '.join(dropped)}." if dropped else ""
    if result is None:
        table.notes.append(f"Not ranked: {len(blocks)} networks over {count} blocks, too few for the test "
                           f"(at least 2 networks and 5 blocks).{left_out}")
        return table
    ranks = result.rankdf.sort_values("meanrank")
    for model, row in ranks.iterrows():
        close = [other for other, r in ranks.iterrows()
                 if other != model and abs(r["meanrank"] - row["meanrank"]) < result.cd]
        table.add([model, f"{row['meanrank']:.2f}", f"{100 * row['median']:.2f}", ", ".join(close) or "-"])
    verdict = ("the networks differ" if result.pvalue < result.alpha else "no difference between the networks "
               "is shown")
    table.notes.append(f"Friedman p = {result.pvalue:.2g} ({verdict} at alpha {result.alpha:g}); critical "
                       f"difference of mean ranks {result.cd:.2f}: two networks closer than that are not shown to "
                       f"differ.{left_out}")
    return table


def cd_figure(result):
    """autorank's critical-difference diagram; with no ``result``, a figure that says why there is none."""
    import matplotlib.pyplot as plt

    if result is None:
        fig, ax = plt.subplots(figsize=(6, 1.2))
        ax.axis("off")
        ax.text(0.5, 0.5, "too few networks or (shape, seed) blocks to rank", ha="center", va="center")
        return fig
    from autorank import plot_stats

    ax = plot_stats(result, allow_insignificant=True)
    return ax.get_figure() if ax is not None else plt.gcf()
