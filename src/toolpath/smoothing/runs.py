"""One smoothing run of the optimize stage as data: which windows, which (mode, method, encoding) on
each, running one task, and the convergence curves of the optimisers."""

from __future__ import annotations

from collections import Counter

import numpy as np

from toolpath.geometry.labels.split import Split
from toolpath.smoothing.evaluate import convergence, summarise, window_row
from toolpath.smoothing.mealpy_runs import MEALPY_CLASSES
from toolpath.smoothing.methods import BASELINE_ONLY, METHODS, dispatch, problem_from, smooth
from toolpath.smoothing.nacoa import NACOA
from toolpath.smoothing.paper_metric import paired_differences, paper_metric


def per_category(sample: dict, category: int) -> int:
    """``sample.per_category``: one count for every category, or a count per category."""
    count = sample["per_category"]
    if isinstance(count, int):
        return count
    if category not in count and str(category) not in count:
        raise ValueError(f"optimize.sample.per_category has no count for category {category}")
    return int(count[category] if category in count else count[str(category)])


def sample_windows(label: np.ndarray, split: np.ndarray, sample: dict, seed: int) -> list[tuple[int, int, bool]]:
    """(window index, category, runs the baselines) for a seeded draw of test windows per category."""
    rng = np.random.default_rng(seed)
    chosen = []
    for category in sample["categories"]:
        pool = np.flatnonzero((label == category) & (split == Split.TEST))
        wanted = per_category(sample, category)
        picks = rng.choice(pool, size=min(wanted, len(pool)), replace=False)
        with_baselines = category in sample["baseline_categories"]
        chosen += [(int(i), int(category), with_baselines and k < sample["baselines_per_category"])
                   for k, i in enumerate(picks)]
    return chosen


def plan(chosen: list[tuple[int, int, bool]], ocfg: dict) -> list[dict]:
    """Every (window, mode, method, encoding) to run; mealpy methods (both encodings), NACOA with the
    paper's permuting initialisation and NACOA at the head-to-head budget only on the baseline windows,
    in the baseline modes; a mode of ``sample.per_category_by_mode`` only on the first windows of each
    category's draw (the baseline windows are the first too)."""
    unknown = [m for m in ocfg["methods"] if m not in METHODS]
    if unknown:
        raise ValueError(f"optimize.methods has unknown method(s) {', '.join(unknown)}; known: {', '.join(METHODS)}")
    caps = ocfg["sample"].get("per_category_by_mode") or {}
    if unknown := [m for m in caps if m not in ocfg["modes"]]:
        raise ValueError(f"optimize.sample.per_category_by_mode names mode(s) {', '.join(unknown)} not in "
                         f"optimize.modes")
    tasks, rank = [], Counter()
    for index, category, baselines in chosen:
        rank[category] += 1  # this window's place in its category's draw: a cap keeps the first ones
        for mode in ocfg["modes"]:
            if mode in caps and rank[category] > int(caps[mode]):
                continue
            for method in ocfg["methods"]:
                if method in BASELINE_ONLY and (not baselines or mode not in ocfg.get("baseline_modes", ocfg["modes"])):
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
    """Mean convergence per optimiser in ``tube`` mode (``bound`` where no tube ran), plain encoding, on
    the windows every optimiser ran (the baseline windows; all windows when no baseline ran)."""
    baseline_windows = {t["window"] for t in tasks if t["method"] in MEALPY_CLASSES}
    modes = {t["mode"] for t in tasks}
    drawn = next((m for m in ("tube", "bound") if m in modes), None)  # the headline's bound where it ran
    histories: dict[str, list] = {}
    for task, (row, _, history) in zip(tasks, outputs, strict=True):
        if (history and task["mode"] == drawn and task["encoding"] == "plain"
                and (not baseline_windows or task["window"] in baseline_windows)):
            histories.setdefault(task["method"], []).append((history, row["fitness_before"]))
    return convergence(histories)


def study_windows(label: np.ndarray, split: np.ndarray, study: dict, seed: int) -> list[int]:
    """Validation windows (never test) of categories 2-4 for NACOA's convergence study."""
    rng = np.random.default_rng(seed)
    chosen = []
    for category in (2, 3, 4):
        pool = np.flatnonzero((label == category) & (split == Split.VAL))
        chosen += [int(i) for i in rng.choice(pool, size=min(study["windows_per_category"], len(pool)), replace=False)]
    return chosen


def run_study_task(job: tuple[np.ndarray, int, dict, int]) -> float:
    """Fitness NACOA reaches on one window in tube mode with ``generations`` (one study cell)."""
    from dataclasses import replace

    from toolpath.smoothing.methods import nacoa_settings

    window, generations, ocfg, seed = job
    problem = problem_from(window, ocfg, "tube")
    settings = replace(nacoa_settings(ocfg, problem.tolerance), generations=generations)
    return NACOA(settings).solve(problem, seed).objective


def choose_generations(counts: list[int], fitness: np.ndarray, within_pct: float) -> dict:
    """The cheapest generation count whose mean Fitness over the study windows is within ``within_pct``
    per cent of the best count's; ``fitness`` is (counts, windows)."""
    means = fitness.mean(axis=1)
    best = float(means.min())
    chosen = next(c for c, m in zip(counts, means, strict=True) if m <= best * (1.0 + within_pct / 100.0))
    return {"generations": counts, "mean_fitness": means.tolist(), "best_mean_fitness": best,
            "within_pct": within_pct, "chosen": int(chosen), "windows": int(fitness.shape[1])}


def smoother_grid(grid: dict) -> list[tuple[str, dict]]:
    """Every (smoother, its settings) of ``smoother_study``: the mean filter's width x passes and
    Bezier's degree, in the order the study lists them (a tie goes to the first)."""
    values = [grid["windows_per_category"], *grid["mean_filter"]["width"], *grid["mean_filter"]["passes"],
              *grid["bezier"]["degree"]]
    if not all(isinstance(v, int) and not isinstance(v, bool) and v >= 1 for v in values):
        raise ValueError("optimize.smoother_study lists whole numbers >= 1 only")
    if even := [w for w in grid["mean_filter"]["width"] if w % 2 == 0]:
        raise ValueError(f"optimize.smoother_study.mean_filter.width {even} must be odd (a centred mean)")
    means = [("mean_filter", {"width": int(w), "passes": int(p)})
             for w in grid["mean_filter"]["width"] for p in grid["mean_filter"]["passes"]]
    return means + [("bezier", {"degree": int(d)}) for d in grid["bezier"]["degree"]]


def run_smoother_study_task(job: tuple[np.ndarray, str, dict, str, dict]) -> float:
    """The objective (Fitness, certified inside the bound) one smoother setting reaches on one window."""
    window, method, values, mode, ocfg = job
    return smooth(window, method, {**ocfg, method: values}, mode, seed=0, check=False).objective


def study_smoothers(pool, windows: list[np.ndarray], ocfg: dict) -> dict:
    """The smoothers' settings per fidelity mode of ``ocfg["modes"]``: for each of the mean filter and
    Bezier, the setting of :func:`smoother_grid` with the lowest mean Fitness on ``windows``
    (validation windows, never test), as NACOA's generation count is chosen; ``pool`` maps the cells."""
    grid = smoother_grid(ocfg["smoother_study"])
    cells = [(w, method, values, mode, ocfg) for mode in ocfg["modes"] for method, values in grid for w in windows]
    fitness = np.reshape(list(pool.map(run_smoother_study_task, cells, chunksize=16)),
                         (len(ocfg["modes"]), len(grid), len(windows))).mean(axis=-1)
    study: dict = {"windows": len(windows), "modes": {}}
    for mode, means in zip(ocfg["modes"], fitness, strict=True):
        node = study["modes"][mode] = {}
        for method in ("mean_filter", "bezier"):
            rows = [k for k, (m, _) in enumerate(grid) if m == method]
            best = min(rows, key=lambda k: means[k])  # the first of equals: the grid's order
            node[method] = {"settings": [grid[k][1] for k in rows], "mean_fitness": [float(means[k]) for k in rows],
                            "chosen": grid[best][1]}
    return study


def settings_by_mode(ocfg: dict, study: dict) -> dict[str, dict]:
    """``ocfg`` for each fidelity mode, its smoothers set to the study's choice for that mode."""
    return {mode: {**ocfg, **{m: node[m]["chosen"] for m in ("mean_filter", "bezier")}}
            for mode, node in study["modes"].items()}


def summarise_run(rows: list[dict], chosen: list[tuple[int, int, bool]], tasks: list[dict], ocfg: dict, study: dict,
                  seed: int, smoother_study: dict | None = None) -> dict:
    """The stage's deterministic summary: :func:`summarise`'s all-category means, the paper's metric on
    categories 2-4 with intervals, Table 6's paired differences (NACOA at the matched budget minus each
    baseline, on the baseline windows), the convergence study and the sample; ``seed`` draws the
    bootstrap resamples."""
    mapping = {int(k): v for k, v in ocfg["dispatch"].items()}
    categories = sorted({c for _, c, _ in chosen})
    summary = summarise(rows, {c: dispatch(c, mapping) for c in categories})
    summary["paper_metric"] = paper_metric(rows, mapping, seed)
    summary["head_to_head_paired"] = paired_differences([r for r in rows if r["baseline_window"]], "nacoa_matched",
                                                        seed)
    summary["convergence_study"] = study
    if smoother_study is not None:
        summary["smoother_study"] = smoother_study
    summary["sample"] = {"windows": len(chosen), "runs": len(tasks),
                         "per_category": {str(c): sum(1 for _, k, _ in chosen if k == c) for c in categories}}
    return summary
