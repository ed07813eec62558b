"""Sec. 5.2.4's metric on the windows Sec. 5.3 smooths, with 95 % bootstrap intervals over windows.

The paper reports one reduction per method (mean filter 54 %, Bezier 67 %, NACOA 78 %) and its
dispatch (Sec. 5.3) leaves category 1 alone.  Per fidelity mode and method, on the plain encoding:

* ``categories_2_4``: the mean of per-window LocalCurvature reductions over categories 2-4 pooled,
  and the reduction of the summed LocalCurvature (``1 - sum after / sum before``), each with a 95 %
  percentile bootstrap interval resampling windows (scipy.stats.bootstrap, seeded);
* ``per_category``: the same per category 2, 3, 4; ``category_1`` apart ("left alone by the dispatch");
* ``dispatch``: Sec. 5.3's row, each window of category 2-4 smoothed by its category's method;
* ``ranking``: methods ordered by the pooled mean, with the share of paired bootstrap resamples (the
  same windows drawn for every method) in which that order holds.

Windows a method returned unchanged are counted (a reduction of 0) and flagged ``no_move``.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Mapping

import numpy as np

SMOOTHED = (2, 3, 4)
RESAMPLES = 2000
CONFIDENCE = 0.95


def _interval(values: np.ndarray, statistic, rng: np.random.Generator) -> list[float]:
    from scipy.stats import bootstrap

    if len(values[0]) < 2:
        return [float("nan"), float("nan")]
    result = bootstrap(values, statistic, n_resamples=RESAMPLES, confidence_level=CONFIDENCE, method="percentile",
                       paired=True, vectorized=True, random_state=rng)
    return [float(result.confidence_interval.low), float(result.confidence_interval.high)]


def _mean(reduction, axis=-1):
    return np.mean(reduction, axis=axis)


def _summed(before, after, axis=-1):
    return 100.0 * (1.0 - np.sum(after, axis=axis) / np.sum(before, axis=axis))


def describe(rows: list[dict], rng: np.random.Generator) -> dict:
    """Mean and summed LocalCurvature reduction of ``rows`` with their intervals, and the no-move count."""
    reduction = np.array([r["reduction_pct"] for r in rows], dtype=np.float64)
    before = np.array([r["local_curvature_before"] for r in rows], dtype=np.float64)
    after = np.array([r["local_curvature_after"] for r in rows], dtype=np.float64)
    return {"windows": len(rows), "mean_reduction_pct": float(reduction.mean()),
            "mean_reduction_ci": _interval((reduction,), _mean, rng),
            "summed_reduction_pct": float(_summed(before, after)),
            "summed_reduction_ci": _interval((before, after), _summed, rng),
            "no_move": int(sum(1 for r in rows if r.get("no_move")))}


def paper_metric(rows: Iterable[dict], dispatch: Mapping[int, str], seed: int) -> dict:
    """``{mode: {"methods": {method: {...}}, "dispatch": {...}, "ranking": {...}}}`` (see the module
    docstring) for the plain-encoding rows of every method that ran on the whole sample."""
    rng = np.random.default_rng(seed)
    grouped: dict[str, dict[str, list[dict]]] = defaultdict(lambda: defaultdict(list))
    for r in rows:
        if r["encoding"] == "plain":
            grouped[r["mode"]][r["method"]].append(r)
    out: dict = {}
    for mode, methods in sorted(grouped.items()):
        counts = {m: len(v) for m, v in methods.items()}
        whole = [m for m, c in counts.items() if c == max(counts.values())]  # methods that ran on every window
        node: dict = {"methods": {}}
        for method in sorted(whole):
            members = methods[method]
            smoothed = [r for r in members if int(r["category"]) in SMOOTHED]
            entry = {"categories_2_4": describe(smoothed, rng) if smoothed else None,
                     "per_category": {str(c): describe(sel, rng) for c in SMOOTHED
                                      if (sel := [r for r in members if int(r["category"]) == c])}}
            ones = [r for r in members if int(r["category"]) == 1]
            entry["category_1"] = describe(ones, rng) if ones else None
            node["methods"][method] = entry
        picked = [r for m in whole for r in methods[m]
                  if int(r["category"]) in SMOOTHED and dispatch.get(int(r["category"])) == m]
        if picked:
            chosen = {str(c): dispatch[c] for c in SMOOTHED if c in dispatch}
            node["dispatch"] = {**describe(picked, rng), "methods": chosen}
        node["ranking"] = ranking({m: [r for r in methods[m] if int(r["category"]) in SMOOTHED] for m in whole}, rng)
        out[mode] = node
    return out


def ranking(rows: Mapping[str, list[dict]], rng: np.random.Generator) -> dict:
    """Methods by pooled mean reduction, best first, and the share of paired bootstrap resamples of
    windows in which the same order holds (every method ran on the same windows, in the same order)."""
    keyed = {m: {(r["window"]): r["reduction_pct"] for r in members} for m, members in rows.items() if members}
    if len(keyed) < 2:
        return {"order": list(keyed), "probability": float("nan")}
    windows = sorted(set.intersection(*(set(k) for k in keyed.values())))
    names = sorted(keyed)
    table = np.array([[keyed[m][w] for w in windows] for m in names])  # (methods, windows)
    order = [names[i] for i in np.argsort(-table.mean(axis=1), kind="stable")]
    draws = rng.integers(0, len(windows), size=(RESAMPLES, len(windows)))
    means = table[:, draws].mean(axis=2)  # (methods, resamples)
    ranks = np.argsort(-means, axis=0, kind="stable")
    drawn = [" > ".join(names[i] for i in column) for column in ranks.T]
    shares = {o: drawn.count(o) / RESAMPLES for o in sorted(set(drawn))}
    return {"order": order, "probability": shares.get(" > ".join(order), 0.0), "orders": shares,
            "windows": len(windows)}


def paired_differences(rows: Iterable[dict], reference: str, seed: int) -> dict:
    """``{mode: {method: {"windows", "mean_difference_pct", "ci"}}}``: ``reference``'s curvature
    reduction minus each other method's, on the windows both ran (plain encoding, and each shifted
    variant as ``method@shifted``), with a 95 % bootstrap interval over those windows."""
    rng = np.random.default_rng(seed)
    table: dict[tuple[str, str], dict] = defaultdict(dict)
    for r in rows:
        name = r["method"] if r["encoding"] == "plain" else f"{r['method']}@{r['encoding']}"
        table[(r["mode"], name)][r["window"]] = r["reduction_pct"]
    out: dict = {}
    for (mode, name), by_window in sorted(table.items()):
        ours = table.get((mode, reference))
        if name == reference or not ours:
            continue
        common = sorted(set(ours) & set(by_window))
        if not common:
            continue
        diff = np.array([ours[w] - by_window[w] for w in common], dtype=np.float64)
        out.setdefault(mode, {})[name] = {"windows": len(common), "mean_difference_pct": float(diff.mean()),
                                          "ci": _interval((diff,), _mean, rng)}
    return out
