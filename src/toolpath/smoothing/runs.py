"""One smoothing run of the optimize stage as data: which windows, which (mode, method, encoding) on
each, running one task, and the convergence curves of the optimisers."""

from __future__ import annotations

import numpy as np

from toolpath.labels.split import Split
from toolpath.smoothing.evaluate import convergence, window_row
from toolpath.smoothing.mealpy_runs import MEALPY_CLASSES
from toolpath.smoothing.methods import BASELINE_ONLY, METHODS, smooth


def sample_windows(label: np.ndarray, split: np.ndarray, sample: dict, seed: int) -> list[tuple[int, int, bool]]:
    """(window index, category, runs the baselines) for a seeded draw of test windows per category."""
    rng = np.random.default_rng(seed)
    chosen = []
    for category in sample["categories"]:
        pool = np.flatnonzero((label == category) & (split == Split.TEST))
        picks = rng.choice(pool, size=min(sample["per_category"], len(pool)), replace=False)
        with_baselines = category in sample["baseline_categories"]
        chosen += [(int(i), int(category), with_baselines and k < sample["baselines_per_category"])
                   for k, i in enumerate(picks)]
    return chosen


def plan(chosen: list[tuple[int, int, bool]], ocfg: dict) -> list[dict]:
    """Every (window, mode, method, encoding) to run; mealpy methods (both encodings) and NACOA with the
    paper's permuting initialisation only on the baseline windows."""
    unknown = [m for m in ocfg["methods"] if m not in METHODS]
    if unknown:
        raise ValueError(f"optimize.methods has unknown method(s) {', '.join(unknown)}; known: {', '.join(METHODS)}")
    tasks = []
    for index, category, baselines in chosen:
        for mode in ocfg["modes"]:
            for method in ocfg["methods"]:
                if method in BASELINE_ONLY and not baselines:
                    continue
                for encoding in ocfg["encodings"] if method in MEALPY_CLASSES else ["plain"]:
                    tasks.append({"window": index, "category": category, "baseline_window": baselines,
                                  "mode": mode, "method": method, "encoding": encoding})
    return tasks


def run_task(job: tuple[dict, np.ndarray, dict, int]) -> tuple[dict, np.ndarray, list[float]]:
    task, window, ocfg, seed = job
    result = smooth(window, task["method"], ocfg, task["mode"], seed, task["encoding"])
    return window_row(window, result, **task), result.points, result.history


def convergence_curves(tasks: list[dict], outputs: list) -> dict[str, np.ndarray]:
    """Mean convergence per optimiser in ``bound`` mode, plain encoding, on the windows every
    optimiser ran (the baseline windows; all windows when no baseline ran)."""
    baseline_windows = {t["window"] for t in tasks if t["method"] in MEALPY_CLASSES}
    histories: dict[str, list] = {}
    for task, (row, _, history) in zip(tasks, outputs, strict=True):
        if (history and task["mode"] == "bound" and task["encoding"] == "plain"
                and (not baseline_windows or task["window"] in baseline_windows)):
            histories.setdefault(task["method"], []).append((history, row["fitness_before"]))
    return convergence(histories)
