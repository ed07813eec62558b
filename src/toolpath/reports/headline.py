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


def headline(layout: Layout, shapes: Iterable[str], models: Iterable[str]) -> tuple[dict[str, float], dict[str, str]]:
    """(metrics, tags): Table 3 test accuracy per shape and model, the INT8 accuracy drop, the mean
    curvature reduction and machining time saved in bound mode per paper method, the corner methods'
    mean reduction per case; tags name the best learned model per shape by test accuracy."""
    metrics: dict[str, float] = {}
    tags: dict[str, str] = {}
    for shape in shapes:
        accuracy = {}
        for model in models:
            found = _load(layout.train_metrics(shape, model), f"train@{shape}")
            if found is None:
                continue
            seeds = found["replicates"]
            if seeds["degenerate"]:  # flagged; an all-degenerate model is never scored
                metrics[f"table3.{shape}.{model}.degenerate_seeds"] = float(seeds["degenerate"])
            if seeds["degenerate"] == seeds["replicates"]:
                continue
            figure = seeds["test"]["accuracy"]
            accuracy[model] = figure["mean"]
            metrics[f"table3.{shape}.{model}.test_accuracy"] = figure["mean"]
            if figure["sd"] is not None:
                metrics[f"table3.{shape}.{model}.test_accuracy_sd"] = figure["sd"]
            for replicate, value in figure["per_seed"].items():
                metrics[f"table3.{shape}.{model}.test_accuracy_{replicate}"] = value
        learned = {m: a for m, a in accuracy.items() if m != "rule"}
        if learned:
            tags[f"best_model.{shape}"] = max(sorted(learned), key=learned.get)
        for model, entry in (_load(layout.qat_metrics(shape), f"qat@{shape}") or {}).items():
            if isinstance(entry, dict) and "accuracy_drop_points" in entry:
                metrics[f"int8.{shape}.{model}.accuracy_drop_points"] = entry["accuracy_drop_points"]
        optimized = _load(layout.optimize_summary(shape), f"optimize@{shape}") or {}
        smoothing = optimized.get("methods", {}).get("bound", {}).get("plain", {})
        planned = _load(layout.feedrate_summary(shape), f"feedrate@{shape}") or {}
        timing = planned.get("methods", {}).get("bound", {}).get("plain", {})
        paper_metric = optimized.get("paper_metric", {})
        for mode, node in paper_metric.items():  # Sec. 5.2.4 on categories 2-4, the parent run's headline
            for method, entry in node.get("methods", {}).items():
                if method in PAPER_SMOOTHERS and entry.get("categories_2_4"):
                    pooled = entry["categories_2_4"]
                    metrics[f"smoothing.{shape}.{mode}.{method}.cat2_4_reduction_pct"] = pooled["mean_reduction_pct"]
                    metrics[f"smoothing.{shape}.{mode}.{method}.cat2_4_ci_low"] = pooled["mean_reduction_ci"][0]
                    metrics[f"smoothing.{shape}.{mode}.{method}.cat2_4_ci_high"] = pooled["mean_reduction_ci"][1]
            if "dispatch" in node:
                dispatched = node["dispatch"]["mean_reduction_pct"]
                metrics[f"smoothing.{shape}.{mode}.dispatch.cat2_4_reduction_pct"] = dispatched
        for method in PAPER_SMOOTHERS:
            if method in smoothing:  # the former headline: every category, disc bound
                every = smoothing[method]["mean_reduction_pct"]
                metrics[f"smoothing.{shape}.{method}.all_categories_reduction_pct"] = every
                metrics[f"smoothing.{shape}.{method}.max_hausdorff_mm"] = smoothing[method]["max_hausdorff_mm"]
            if method in timing:
                metrics[f"feedrate.{shape}.{method}.time_saved_pct"] = timing[method]["time_saved_pct"]
    for case, record in ((_load(layout.corner_metrics, "corner") or {}).get("cases", {})).items():
        for method, entry in record["methods"].items():
            if entry.get("mean_reduction_pct") is not None:
                metrics[f"corner.{case}.{method}.mean_reduction_pct"] = entry["mean_reduction_pct"]
    return metrics, tags
