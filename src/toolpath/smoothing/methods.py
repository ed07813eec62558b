"""Every smoothing method behind one call, and the roughness-driven dispatch of Sec. 5.3.

``smooth(window, method, cfg, seed)`` builds the shared :class:`SmoothingProblem` from ``cfg`` (the
``optimize`` section of the config) and runs one method on it:

* ``mean_filter`` and ``bezier`` are one-shot smoothers; in ``bound`` mode their result is projected
  onto the tolerance discs like every optimiser's candidates, so no method leaves the bound (and
  :func:`smooth` checks the exact two-sided distance of every ``bound`` result before returning it);
* ``nacoa`` is :class:`toolpath.smoothing.nacoa.NACOA`; ``nacoa_permute`` the same with the paper's
  permuting initialisation;
* ``coa``, ``hba``, ``avoa``, ``scso``, ``esoa``, ``pso`` are mealpy's, given NACOA's budget of evaluations
  (computed from its settings), its first population and the same seed.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from toolpath.geometry.hausdorff import hausdorff
from toolpath.smoothing.mealpy_runs import MEALPY_CLASSES, encoding_shift, run_mealpy
from toolpath.smoothing.nacoa import NACOA, NACOASettings, initial_population
from toolpath.smoothing.problem import ProblemBatch, SmoothingProblem
from toolpath.smoothing.result import SmoothingResult
from toolpath.smoothing.smoothers import bezier_fit, mean_filter

SMOOTHERS = ("mean_filter", "bezier")
# "nacoa_permute" is NACOA with the paper's initialisation as written (Sec. 4.2.1: interior points
# permuted), run beside the default to show what that does to a toolpath
METHODS = (*SMOOTHERS, "nacoa", "nacoa_permute", *MEALPY_CLASSES)
BASELINE_ONLY = ("nacoa_permute", *MEALPY_CLASSES)  # run on the baseline windows only
ENCODINGS = ("plain", "shifted")
UNTOUCHED = "none"


def problem_from(window: np.ndarray, cfg: Mapping, mode: str) -> SmoothingProblem:
    return SmoothingProblem(window, mode=mode, tolerance=cfg["tolerance"], weight=cfg["penalty_weight"])


def nacoa_settings(cfg: Mapping, tolerance: float) -> NACOASettings:
    """NACOA's settings from the config; its random term and first population span the tolerance."""
    values = {k: v for k, v in cfg["nacoa"].items() if k != "_target_"}  # the config's class is NACOASettings
    values.setdefault("perturbation", tolerance)
    return NACOASettings(**values)


def nacoa_budget(settings: NACOASettings) -> int:
    """Evaluations NACOA spends (first population, HBA phase, G generations of candidate + gradient)."""
    per_gradient = {"exact": 1, "off": 0}.get(settings.gradient)
    if per_gradient is None:
        raise ValueError("the mealpy budget is defined for NACOA with the exact gradient (or none)")
    n = settings.population
    return n * (1 + settings.hba_generations) + n * settings.generations * (1 + per_gradient)


def search_box(problem: SmoothingProblem, cfg: Mapping) -> float:
    """Half-width of the box mealpy searches per coordinate: the tolerance in ``bound`` mode (each
    point's disc is inside that box), ``cfg.box`` mm otherwise."""
    return problem.tolerance if problem.mode == "bound" else float(cfg["box"])


def smooth(window: np.ndarray, method: str, cfg: Mapping, mode: str, seed: int,
           encoding: str = "plain", check: bool = True) -> SmoothingResult:
    """Run ``method`` on one window under fidelity ``mode``; ``encoding`` applies to mealpy methods.
    ``check=False`` skips the two-sided check of ``bound`` mode, for a caller that measures the
    result itself (``toolpath smooth`` does, after rounding to the written precision)."""
    result = _run(window, method, cfg, mode, seed, encoding)
    if mode == "bound" and check:
        deviation = float(hausdorff(window, result.points))
        if deviation > cfg["tolerance"] + 1e-9:  # the projection makes this impossible; never ship it
            raise AssertionError(f"{method} returned a window {deviation:.6f} mm from the original, "
                                 f"over the tolerance {cfg['tolerance']} mm")
    return result


TOGETHER = ("mean_filter", "nacoa")  # the methods :func:`smooth_together` runs on many windows at once


def smooth_together(windows: list[np.ndarray], method: str, cfg: Mapping, mode: str,
                    seeds: list[int]) -> list[SmoothingResult]:
    """``smooth(window, method, cfg, mode, seed, check=False)`` of each window, with the same results:
    windows of one length go through :data:`TOGETHER`'s methods side by side (one NumPy call per step
    for all of them; NACOA keeps a generator per seed), every other method one window at a time."""
    if method not in TOGETHER or len({len(w) for w in windows}) > 1:
        return [smooth(w, method, cfg, mode, seed, check=False) for w, seed in zip(windows, seeds, strict=True)]
    problems = [problem_from(window, cfg, mode) for window in windows]
    if method == "nacoa":
        return NACOA(nacoa_settings(cfg, problems[0].tolerance)).solve_many(problems, seeds)
    began = time.perf_counter()
    batch = ProblemBatch(problems)
    raw = mean_filter(batch.windows[:, 0], **cfg["mean_filter"])
    points = batch.points(batch.displacement(raw[:, None]))[:, 0]
    objectives = batch.score(points[:, None])[:, 0].tolist()
    seconds = (time.perf_counter() - began) / len(windows)
    return [SmoothingResult(points=p, objective=o, evaluations=1, seconds=seconds)
            for p, o in zip(points, objectives, strict=True)]


def _run(window: np.ndarray, method: str, cfg: Mapping, mode: str, seed: int, encoding: str) -> SmoothingResult:
    if method not in METHODS:
        raise ValueError(f"unknown smoothing method {method!r}; known: {', '.join(METHODS)}")
    if encoding not in ENCODINGS:
        raise ValueError(f"unknown encoding {encoding!r}; known: {', '.join(ENCODINGS)}")
    problem = problem_from(window, cfg, mode)
    if method in SMOOTHERS:
        began = time.perf_counter()
        raw = (mean_filter(problem.window, **cfg["mean_filter"]) if method == "mean_filter"
               else bezier_fit(problem.window, **cfg["bezier"]))
        points = problem.points(problem.displacement(raw))
        return SmoothingResult(points=points, objective=float(problem.score(points)), evaluations=1,
                               seconds=time.perf_counter() - began)
    settings = nacoa_settings(cfg, problem.tolerance)
    if method == "nacoa":
        return NACOA(settings).solve(problem, seed)
    if method == "nacoa_permute":
        return NACOA(replace(settings, init="permute")).solve(problem, seed)
    box = search_box(problem, cfg)
    start = initial_population(problem, settings, np.random.default_rng(seed))
    shift = encoding_shift(problem, box, seed + 1) if encoding == "shifted" else None
    return run_mealpy(method, problem, population=settings.population, budget=nacoa_budget(settings), box=box,
                      seed=seed, start=start, shift=shift)


def dispatch(category: int, mapping: Mapping) -> str:
    """Sec. 5.3: the method for a window of Table 1 ``category``; category 1 is left untouched."""
    if category == 1:
        return UNTOUCHED
    key = category if category in mapping else str(category)
    if key not in mapping:
        raise ValueError(f"optimize.dispatch has no method for category {category}")
    method = mapping[key]
    if method not in (*METHODS, UNTOUCHED):
        raise ValueError(f"optimize.dispatch maps category {category} to unknown method {method!r}")
    return method
