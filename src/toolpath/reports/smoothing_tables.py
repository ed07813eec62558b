"""Smoothing tables of the report: Sec. 5.2.4's metric on the windows Sec. 5.3 smooths (categories 2-4,
with intervals), the old all-category means under their own name, and Table 6 at equal charged
evaluations with paired differences.  Inputs are the ``optimize`` stage's summaries per shape
(``metrics``) and its timing files (``timing``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from toolpath.reports.paper import PAPER_REDUCTION, PAPER_TABLE6
from toolpath.reports.tables import Table

PAPER_METHODS = ("mean_filter", "bezier", "nacoa")
MODE_LABEL = {"none": "paper (no bound)", "tube": "bound (tube)", "bound": "bound (discs, stricter)",
              "penalty": "penalty"}
METHOD_LABEL = {"mean_filter": "mean filter", "bezier": "Bezier", "nacoa": "NACOA",
                "nacoa_permute": "NACOA (permute init)", "nacoa_matched": "NACOA (matched budget)", "coa": "COA",
                "hba": "HBA", "avoa": "AVOA", "scso": "SCSO", "esoa": "ESOA", "pso": "PSO"}
# whose Fitness is evaluated for the whole population in one NumPy call (the rest: one call per individual)
VECTORISED = ("nacoa", "nacoa_matched", "nacoa_permute", "mean_filter", "bezier")
PAPER_ORDER = " > ".join(sorted(PAPER_METHODS, key=lambda m: -PAPER_REDUCTION[m]))


def label(method: str) -> str:
    base, _, encoding = method.partition("@")
    return METHOD_LABEL.get(base, base) + (f" ({encoding})" if encoding else "")


def with_interval(figure: Mapping | None, key: str = "mean_reduction") -> str:
    """``mean [low, high]`` of a :func:`toolpath.smoothing.paper_metric.describe` entry."""
    if not figure:
        return "-"
    low, high = figure[f"{key}_ci"]
    if low is None or high is None:  # under 2 windows: no interval (NaN, written as null)
        return f"{figure[f'{key}_pct']:.1f} [no interval]"
    return f"{figure[f'{key}_pct']:.1f} [{low:.1f}, {high:.1f}]"


def against_paper(figure: Mapping, paper: float) -> str:
    """Where the paper's figure lies against our 95 % interval: the sentence the report may say."""
    low, high = figure["mean_reduction_ci"]
    if low is None or high is None:
        return "too few windows for an interval"
    if low > paper:
        return f"above the paper's {paper:.0f} %"
    if high < paper:
        return f"below the paper's {paper:.0f} %"
    return f"no difference from the paper's {paper:.0f} % shown"


def paper_metric_table(metrics: Mapping[str, Mapping]) -> Table:
    """Per shape, mode and method (and the Sec. 5.3 dispatch): the mean of per-window LocalCurvature
    reductions over categories 2-4 with its interval, beside the paper; the summed reduction; each
    category; category 1 apart."""
    headers = ["shape", "mode", "method", "windows (2-4)", "categories 2-4, mean % [95 % CI]", "against the paper",
               "summed LocalCurvature % [95 % CI]", "category 2", "category 3", "category 4",
               "category 1 (left alone by the dispatch)"]
    table = Table("Sec. 5.2.4's reduction on the windows Sec. 5.3 smooths (categories 2-4), ours beside the paper",
                  headers)
    for shape, m in metrics.items():
        for mode, node in m.get("paper_metric", {}).items():
            for method in [*PAPER_METHODS, *sorted(set(node["methods"]) - set(PAPER_METHODS))]:
                entry = node["methods"].get(method)
                if not entry or not entry["categories_2_4"]:
                    continue
                pooled = entry["categories_2_4"]
                verdict = against_paper(pooled, PAPER_REDUCTION[method]) if method in PAPER_REDUCTION else "-"
                table.add([shape, MODE_LABEL.get(mode, mode), label(method), pooled["windows"], with_interval(pooled),
                           verdict, with_interval(pooled, "summed_reduction"),
                           *(with_interval(entry["per_category"].get(str(c))) for c in (2, 3, 4)),
                           with_interval(entry["category_1"])])
            if "dispatch" in node:
                d = node["dispatch"]
                table.add([shape, MODE_LABEL.get(mode, mode), "Sec. 5.3 dispatch (" + ", ".join(
                    f"{c}: {label(x)}" for c, x in sorted(d["methods"].items())) + ")", d["windows"], with_interval(d),
                    "-", with_interval(d, "summed_reduction"), "-", "-", "-", "left alone"])
    table.notes += [
        "Mean of per-window LocalCurvature (Eq. 3) reductions over the seeded sample of test windows of categories "
        "2-4 (the windows Sec. 5.3 smooths); 95 % percentile bootstrap intervals resample windows. The summed "
        "column is 1 - (sum after / sum before). 'Against the paper' compares the paper's Sec. 5.2.4 figure "
        "(mean filter 54 %, Bezier 67 %, NACOA 78 %) with our interval: above / below only where the interval "
        "excludes it.",
        "Bound (tube): the smoothed window within the tolerance of the original both ways, points free to slide "
        "along it (checked by the exact two-sided distance); discs: each point within the tolerance of its own "
        "place (stricter).",
    ]
    table.notes += ranking_notes(metrics)
    return table


def ranking_notes(metrics: Mapping[str, Mapping]) -> list[str]:
    """Per shape and mode, the paper's three methods by pooled mean (categories 2-4), with the share of
    paired bootstrap resamples in which our order holds and in which the paper's does."""
    notes = []
    for shape, m in metrics.items():
        for mode, node in m.get("paper_metric", {}).items():
            rank = node.get("ranking", {})
            if not all(k in rank.get("order", []) for k in PAPER_METHODS):
                continue
            orders = {o: share for o, share in rank["orders"].items()}
            ours = " > ".join(k for k in rank["order"] if k in PAPER_METHODS)
            # the share of resamples in which the three methods fall in the paper's order
            paper_share = sum(share for o, share in orders.items() if _sub_order(o) == PAPER_ORDER)
            ours_share = sum(share for o, share in orders.items() if _sub_order(o) == ours)
            if ours == PAPER_ORDER:
                verdict = "the paper's order"
            elif paper_share < 0.05:
                verdict = f"differs from the paper's {_names(PAPER_ORDER)} (which holds in {100 * paper_share:.0f} %)"
            else:
                verdict = (f"not shown to differ from the paper's {_names(PAPER_ORDER)} (which holds in "
                           f"{100 * paper_share:.0f} % of resamples)")
            notes.append(f"{shape}, {MODE_LABEL.get(mode, mode)}: {_names(ours)} in {100 * ours_share:.0f} % of "
                         f"resamples; {verdict}.")
    return notes


def _sub_order(order: str) -> str:
    return " > ".join(k for k in order.split(" > ") if k in PAPER_METHODS)


def _names(order: str) -> str:
    return " > ".join(label(k) for k in order.split(" > "))


def _mean(values: Sequence[float]) -> float:
    return float(np.mean(values)) if len(values) else float("nan")


def table6(metrics: Mapping[str, Mapping], timing: Mapping[str, Mapping]) -> Table:
    """Table 6 on the windows every optimiser ran (category 4, NACOA's dispatch), at equal charged
    evaluations, pooled over shapes: time, charged evaluations, whether Fitness is vectorised, Eq. 34
    efficiency (ours), reduction and deviation per mode, windows it left unchanged; the paper beside."""
    shapes = list(metrics)
    # the modes the baselines ran in (the one-shot smoothers and NACOA run on those windows in every mode)
    modes = [mode for mode in MODE_LABEL
             if any("nacoa_matched" in metrics[s].get("head_to_head", {}).get(mode, {}) for s in shapes)]
    methods = sorted({m for s in shapes for mode in modes for m in metrics[s].get("head_to_head", {}).get(mode, {})
                      if m != "nacoa"},  # NACOA at the full size spends ~2000x the budget: not a head-to-head
                     key=lambda m: (not m.startswith("nacoa"), m))
    first = modes[-1] if modes else "tube"
    headers = ["method", "time per window (s)", "charged evaluations", "Fitness vectorised", "complexity",
               "efficiency (Eq. 34, ours)",
               *(h for mode in modes for h in (f"reduction, {MODE_LABEL[mode]} (%)",
                                                f"max two-sided deviation, {MODE_LABEL[mode]} (mm)",
                                                f"no move, {MODE_LABEL[mode]}")),
               "paper: time / GPU / efficiency"]
    table = Table("Table 6: optimisers on the same windows at equal charged evaluations, ours beside the paper",
                  headers)

    def pooled(method: str, key: str, mode: str, source: Mapping = metrics) -> list[float]:
        return [source[s]["head_to_head"][mode][method][key] for s in shapes
                if method in source[s].get("head_to_head", {}).get(mode, {})]

    def complexity(method: str) -> str:  # as the optimize stage's timing file states it
        found = (timing.get(s, {}).get("head_to_head", {}).get(first, {}).get(method, {}).get("complexity")
                 for s in shapes)
        return next((c for c in found if c), "-")

    for method in methods:
        base = method.partition("@")[0]
        paper = PAPER_TABLE6.get("nacoa" if base == "nacoa_matched" else base)
        cells: list[object] = [label(method), f"{_mean(pooled(method, 'mean_seconds', first, timing)):.3g}",
                               f"{_mean(pooled(method, 'mean_evaluations', first)):.0f}",
                               "yes" if base in VECTORISED else "no (one call per individual)",
                               complexity("nacoa" if base == "nacoa_matched" else base),
                               f"{_mean(pooled(method, 'efficiency', first, timing)):.3g}"]
        for mode in modes:
            moves = pooled(method, "no_move", mode)
            cells += [f"{_mean(pooled(method, 'mean_reduction_pct', mode)):.1f}",
                      f"{max(pooled(method, 'max_hausdorff_mm', mode), default=float('nan')):.3f}",
                      f"{int(sum(moves))} of {int(sum(pooled(method, 'windows', mode)))}" if moves else "-"]
        cells.append(f"{paper['minutes']} min / {paper['gpu_percent']} % / {paper['efficiency']}" if paper else "-")
        table.add(cells)
    windows = sum(metrics[s]["head_to_head"][first]["nacoa_matched"]["windows"] for s in shapes
                  if "nacoa_matched" in metrics[s].get("head_to_head", {}).get(first, {}))
    table.notes += [
        f"Pooled over {len(shapes)} shapes, {windows} category-4 windows that every method ran, each swarm method "
        "given the same charged budget (the one-shot smoothers spend only what their column says; NACOA with "
        "the paper's initialisation runs at the full size, as its charged count shows): NACOA at the head-to-head "
        "settings, a gradient charged as Eq. 23's 2 evaluations "
        "per coordinate whether computed that way or exactly, and every mealpy baseline given that many "
        "evaluations from NACOA's first population. Times are seconds per window on one CPU core; 'Fitness "
        "vectorised' says whether a method evaluates its whole population in one NumPy call (mealpy calls a "
        "Python function per individual), which is most of the time difference. The paper's times are minutes on "
        "an RTX 4070 for an unstated workload. Efficiency: Eq. 34 leaves its terms undefined; ours is the Fitness "
        "reduction (Eq. 10) per second. 'No move': windows returned unchanged, counted as a 0 % reduction.",
        "`(shifted)`: the same optimiser on a search space shifted so that the origin is not the original path.",
    ]
    table.notes += paired_notes(metrics)
    return table


def paired_notes(metrics: Mapping[str, Mapping]) -> list[str]:
    """Per shape and mode, NACOA (matched budget) against the best baseline by mean reduction: the paired
    difference with its interval, and the sentence it allows."""
    notes = []
    for shape, m in metrics.items():
        for mode, diffs in m.get("head_to_head_paired", {}).items():
            head = m.get("head_to_head", {}).get(mode, {})
            rivals = {k: v for k, v in diffs.items() if k.partition("@")[0] not in ("nacoa", "nacoa_permute")}
            if not rivals:
                continue
            best = max(rivals, key=lambda k: head.get(k, {}).get("mean_reduction_pct", -np.inf))
            d = rivals[best]
            low, high = d["ci"]
            if low is None or high is None:
                notes.append(f"{shape}, {MODE_LABEL.get(mode, mode)}: NACOA (matched budget) against {label(best)} "
                             f"on {d['windows']} window(s): too few for an interval.")
                continue
            verdict = ("NACOA is better" if low > 0 else "NACOA is worse" if high < 0 else "no difference shown")
            notes.append(f"{shape}, {MODE_LABEL.get(mode, mode)}: NACOA (matched budget) minus the best baseline "
                         f"({label(best)}) = {d['mean_difference_pct']:+.1f} points [{low:+.1f}, {high:+.1f}] over "
                         f"{d['windows']} windows: {verdict}.")
    return notes


def study_table(metrics: Mapping[str, Mapping]) -> Table:
    """NACOA's convergence study per shape: mean Fitness reached on validation windows per generation
    count, and the count the stage chose (the cheapest within the stated share of the best)."""
    shapes = [s for s in metrics if "convergence_study" in metrics[s]]
    counts = sorted({g for s in shapes for g in metrics[s]["convergence_study"]["generations"]})
    table = Table("NACOA's generation count (Sec. 4.2.3 leaves it open): mean Fitness (Eq. 10) on validation "
                  "windows, tube mode, N = 1000", ["shape", "windows", *(f"G = {g}" for g in counts), "chosen"])
    for shape in shapes:
        study = metrics[shape]["convergence_study"]
        by_count = dict(zip(study["generations"], study["mean_fitness"], strict=True))
        table.add([shape, study["windows"], *(f"{by_count[g]:.4f}" if g in by_count else "-" for g in counts),
                   f"G = {study['chosen']}"])
    if shapes:
        within = metrics[shapes[0]]["convergence_study"]["within_pct"]
        table.notes.append(f"Chosen: the cheapest count whose mean Fitness is within {within:g} % of the best count's, "
                           "on validation windows of categories 2-4 (never the test windows the tables score).")
        capped = [s for s in shapes if metrics[s]["convergence_study"]["chosen"] == max(
            metrics[s]["convergence_study"]["generations"])]
        if capped:
            table.notes.append(f"On {', '.join(capped)} the largest count tried was chosen: Fitness was still falling, "
                               "so NACOA is not converged there and more generations would reduce more, at their cost.")
    table.notes += smoother_notes(metrics)
    return table


def smoother_notes(metrics: Mapping[str, Mapping]) -> list[str]:
    """The mean filter's and Bezier's settings the optimize stage chose per shape and fidelity mode."""
    notes = []
    for shape, node in metrics.items():
        if "smoother_study" not in node:
            continue
        study = node["smoother_study"]
        chosen = "; ".join(
            f"{MODE_LABEL.get(mode, mode)}: mean filter width {m['mean_filter']['chosen']['width']} x "
            f"{m['mean_filter']['chosen']['passes']} pass(es), Bezier degree {m['bezier']['chosen']['degree']}"
            for mode, m in study["modes"].items())
        edges = [MODE_LABEL.get(mode, mode) for mode, m in study["modes"].items()
                 if any(node["chosen"] in (node["settings"][0], node["settings"][-1]) for node in m.values())]
        notes.append(f"{shape}: the smoothers' settings, chosen per mode as NACOA's count is (lowest mean Fitness on "
                     f"{study['windows']} validation windows of categories 2-4): {chosen}."
                     + (f" In {', '.join(edges)} a setting at an end of its grid won: a heavier or lighter one "
                        "might do better still." if edges else ""))
    return notes
