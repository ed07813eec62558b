"""The pipeline's headline figures, for the MLflow parent run: how did this run do, on one page.

Read from the same DVC outputs as the report; a figure whose file is absent (a smoke profile, a stage
not run) is left out.  Keys use the one metric vocabulary of the project: dotted paths, as DVC
flattens its metrics files (``table3.gear.mcrl.test_accuracy``).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from toolpath.pipeline.artifacts import Layout, read_json

PAPER_SMOOTHERS = ("mean_filter", "bezier", "nacoa")


def _load(path: Path, producer: str) -> dict | None:
    """The metrics file, None when absent (a stage not run); a corrupt one stops with its name."""
    return read_json(path, producer) if path.is_file() else None


def headline(layout: Layout, shapes: Iterable[str], models: Iterable[str],
             anchors: Iterable[str] | None = None) -> tuple[dict[str, float], dict[str, str]]:
    """(metrics, tags) for the parent run, at most 60 figures, each name saying what it is measured against:
    per shape the Table 3 seed-mean test accuracy of MCRL on each input (``anchors``; every model when
    None) and of the best learned model, MCRL's INT8 accuracy drop, the Sec. 5.2.4
    LocalCurvature reduction on categories 2-4 within the tube (``_vs_rough``: against the rough window) of
    each paper smoother and the dispatch, and the machining time each saves (``_vs_g01``); per corner case,
    NURBS + PSO's peak-curvature reduction against method 1 and its time against the G01 corner.  Tags
    name the best learned model per shape (:func:`~toolpath.models.training.replicates.best_learned`).  The
    per-seed, per-category and per-method detail stays on the stage runs."""
    from toolpath.models.training.replicates import best_learned

    metrics: dict[str, float] = {}
    tags: dict[str, str] = {}
    for shape in shapes:
        summaries = {}
        for model in models:
            found = _load(layout.train_metrics(shape, model), f"train@{model}")
            if found is None:
                continue
            seeds = found["replicates"]
            summaries[model] = seeds
        best = best_learned(summaries)
        shown = set(summaries) if anchors is None else {*anchors, best}
        for model, seeds in summaries.items():
            if model in shown and seeds["degenerate"] < seeds["replicates"]:  # degenerate: flagged, never scored
                metrics[f"table3.{shape}.{model}.test_accuracy"] = seeds["test"]["accuracy"]["mean"]
        if best:
            tags[f"best_model.{shape}"] = best
        drop = (_load(layout.qat_metrics("mcrl"), "qat@mcrl") or {}).get(shape, {})
        if isinstance(drop, dict) and "accuracy_drop_points" in drop:
            metrics[f"int8.{shape}.mcrl.accuracy_drop_points_vs_fp32"] = drop["accuracy_drop_points"]
        optimized = _load(layout.optimize_summary(shape), f"optimize@{shape}") or {}
        tube = optimized.get("paper_metric", {}).get("tube", {})
        for method, entry in tube.get("methods", {}).items():
            if method in PAPER_SMOOTHERS and entry.get("categories_2_4"):
                pooled = entry["categories_2_4"]["mean_reduction_pct"]
                metrics[f"smoothing.{shape}.{method}.cat2_4_reduction_pct_vs_rough"] = pooled
        if "dispatch" in tube:
            dispatched = tube["dispatch"]["mean_reduction_pct"]
            metrics[f"smoothing.{shape}.dispatch.cat2_4_reduction_pct_vs_rough"] = dispatched
        planned = _load(layout.feedrate_summary(shape), f"feedrate@{shape}") or {}
        timing = planned.get("methods", {}).get("tube", {}).get("plain", {})
        for method in PAPER_SMOOTHERS:
            if method in timing:
                metrics[f"feedrate.{shape}.{method}.time_saved_pct_vs_g01"] = timing[method]["time_saved_pct"]
    for case, record in ((_load(layout.corner_metrics, "corner") or {}).get("cases", {})).items():
        entry = record["methods"].get("nurbs_pso", {})
        if entry.get("mean_reduction_vs_method1_pct") is not None:
            metrics[f"corner.{case}.nurbs_pso.peak_reduction_pct_vs_method1"] = entry["mean_reduction_vs_method1_pct"]
        if entry.get("time_saved_vs_g01_pct") is not None:
            metrics[f"corner.{case}.nurbs_pso.time_saved_pct_vs_g01"] = entry["time_saved_vs_g01_pct"]
    return metrics, tags
