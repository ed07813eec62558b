"""Per-window rows, per-method summaries and convergence curves of a smoothing run (Table 6, Figs. 8-11)."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable

import numpy as np

from toolpath.geometry.curvature import arc_length, fitness, local_curvature, reduction_pct, smoothness_penalty
from toolpath.geometry.hausdorff import directed_hausdorff
from toolpath.smoothing.result import SmoothingResult

# Table 6's complexity column: the paper's entries where it gives one, ours (same notation: t
# iterations, p population, d dimension, n points) for the rest.
COMPLEXITY = {
    "nacoa": "O(n^2) + O(t p d)", "nacoa_permute": "O(n^2) + O(t p d)",
    "scso": "O(t p d)", "esoa": "O(t p d)", "avoa": "O(t p) + O(t p d)",
    "coa": "O(t p d)", "hba": "O(t p d)", "pso": "O(t p d)", "mean_filter": "O(w n)", "bezier": "O(n k^2)",
}
ROW_FIELDS = ("window", "category", "baseline_window", "mode", "method", "encoding", "local_curvature_before",
              "local_curvature_after", "reduction_pct", "smoothness_before", "smoothness_after",
              "fitness_before", "fitness_after", "hausdorff_mm", "one_sided_mm", "arc_length_change_pct",
              "evaluations", "no_move", "seconds")


def window_row(original: np.ndarray, result: SmoothingResult, **keys) -> dict:
    """One CSV row: LocalCurvature before / after (Eq. 3), SmoothnessPenalty, Eq. 10, deviation.

    ``hausdorff_mm`` is the exact two-sided distance between the two polylines (the quantity ``bound``
    mode caps, and the deviation every table reports); ``one_sided_mm`` is only the farthest point
    of the smoothed path from the original (how far a cut-off noise spike is from the new path is
    missing from it), kept for comparison with the paper's kind of figure.
    """
    w, p = np.asarray(original, dtype=np.float64), result.points
    there, back = float(directed_hausdorff(p, w)), float(directed_hausdorff(w, p))
    before, after = float(local_curvature(w)), float(local_curvature(p))
    length = float(arc_length(w))
    return {**keys, "local_curvature_before": before, "local_curvature_after": after,
            "reduction_pct": reduction_pct(before, after),
            "smoothness_before": float(smoothness_penalty(w)), "smoothness_after": float(smoothness_penalty(p)),
            "fitness_before": float(fitness(w)), "fitness_after": float(fitness(p)),
            "hausdorff_mm": max(there, back), "one_sided_mm": there,
            "arc_length_change_pct": 100.0 * (float(arc_length(p)) - length) / length if length > 0 else 0.0,
            "evaluations": result.evaluations, "no_move": int(np.array_equal(p, w)), "seconds": result.seconds}


def _stats(rows: list[dict]) -> dict:
    red = np.array([r["reduction_pct"] for r in rows])
    return {"windows": len(rows), "mean_reduction_pct": float(red.mean()),
            "median_reduction_pct": float(np.median(red)),
            "max_hausdorff_mm": float(max(r["hausdorff_mm"] for r in rows)),
            "mean_hausdorff_mm": float(np.mean([r["hausdorff_mm"] for r in rows])),
            "max_one_sided_mm": float(max(r["one_sided_mm"] for r in rows)),
            "mean_fitness_after": float(np.mean([r["fitness_after"] for r in rows])),
            "mean_arc_length_change_pct": float(np.mean([r["arc_length_change_pct"] for r in rows])),
            "mean_evaluations": float(np.mean([r["evaluations"] for r in rows])),
            "no_move": int(sum(r.get("no_move", 0) for r in rows))}


def summarise(rows: Iterable[dict], dispatch: dict[int, str]) -> dict:
    """Deterministic summary (no timings): ``methods[mode][encoding][method]`` overall and per category;
    ``dispatch[mode][category]``, the dispatched method's result (Sec. 5.3); and
    ``head_to_head[mode][method or method@shifted]``, every method on the same (baseline) windows."""
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        groups[(r["mode"], r["encoding"], r["method"])].append(r)
        groups[(r["mode"], r["encoding"], r["method"], r["category"])].append(r)
    out: dict = {}
    for key, members in sorted(groups.items(), key=lambda kv: tuple(map(str, kv[0]))):
        mode, encoding, method = key[:3]
        node = out.setdefault(mode, {}).setdefault(encoding, {}).setdefault(method, {})
        if len(key) == 3:
            node.update(_stats(members))
        else:
            node.setdefault("per_category", {})[str(key[3])] = _stats(members)
    dispatched = {}
    for mode in out:
        plain = out[mode].get("plain", {})
        dispatched[mode] = {
            str(c): {"method": m, **({"mean_reduction_pct": 0.0} if m == "none" else
                                     {"mean_reduction_pct": plain[m]["per_category"][str(c)]["mean_reduction_pct"],
                                      "max_hausdorff_mm": plain[m]["per_category"][str(c)]["max_hausdorff_mm"]})}
            for c, m in sorted(dispatch.items()) if m == "none" or str(c) in plain.get(m, {}).get("per_category", {})}
    # Table 6 compares methods on the same windows: those the mealpy baselines ran on
    head: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        if r.get("baseline_window"):
            head[(r["mode"], _head_name(r))].append(r)
    head_to_head: dict = {}
    for (mode, name), members in sorted(head.items()):
        head_to_head.setdefault(mode, {})[name] = _stats(members)
    return {"methods": out, "dispatch": dispatched, "head_to_head": head_to_head}


def _head_name(row: dict) -> str:
    return row["method"] if row["encoding"] == "plain" else f"{row['method']}@{row['encoding']}"


def efficiency(rows: Iterable[dict]) -> float:
    """Eq. 34 with its terms chosen by us: resource = the objective (Eq. 10); the reduction
    ``fitness_before - fitness_after`` achieved, per second of runtime, averaged over windows."""
    values = [(r["fitness_before"] - r["fitness_after"]) / max(r["seconds"], 1e-9) for r in rows]
    return float(np.mean(values)) if values else float("nan")


def timing(rows: Iterable[dict]) -> dict:
    """Table 6's time, evaluations, complexity and efficiency per mode, encoding and method (timings vary
    between runs, so they are kept apart from the deterministic summary)."""
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        groups[(r["mode"], r["encoding"], r["method"])].append(r)
    def entry(method: str, members: list[dict]) -> dict:
        return {"mean_seconds": float(np.mean([r["seconds"] for r in members])),
                "total_seconds": float(np.sum([r["seconds"] for r in members])),
                "mean_evaluations": float(np.mean([r["evaluations"] for r in members])),
                "complexity": COMPLEXITY.get(method, ""), "efficiency": efficiency(members), "windows": len(members)}

    out: dict = {}
    for (mode, encoding, method), members in sorted(groups.items()):
        out.setdefault(mode, {}).setdefault(encoding, {})[method] = entry(method, members)
    head: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:
        if r.get("baseline_window"):
            head[(r["mode"], _head_name(r))].append(r)
    for (mode, name), members in sorted(head.items()):
        out.setdefault("head_to_head", {}).setdefault(mode, {})[name] = entry(members[0]["method"], members)
    return out


def convergence(histories: dict[str, list[tuple[list[float], float]]], points: int = 51) -> dict[str, np.ndarray]:
    """Mean best objective relative to the start, on a common axis of budget fraction 0..1.

    ``histories[method]`` holds ``(history, start_objective)`` per window; each history is the best
    objective per generation, spread evenly over the method's budget.
    """
    grid = np.linspace(0.0, 1.0, points)
    curves = {}
    for method, runs in sorted(histories.items()):
        rel = []
        for history, start in runs:
            h = np.minimum.accumulate(np.asarray(history, dtype=np.float64)) / max(start, 1e-12)
            rel.append(np.interp(grid, np.linspace(0.0, 1.0, len(h)), h) if len(h) > 1 else np.full(points, h[-1]))
        curves[method] = np.mean(rel, axis=0)
    return {"budget_fraction": grid, **curves}
