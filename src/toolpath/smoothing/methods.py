"""Every smoothing method behind one call, and the roughness-driven dispatch of Sec. 5.3.

``smooth(window, method, cfg, seed)`` builds the shared :class:`SmoothingProblem` from ``cfg`` (the
``optimize`` section of the config) and runs one method on it:

* ``mean_filter`` and ``bezier`` are one-shot smoothers; in ``bound`` mode their result is projected
  onto the tolerance discs like every optimiser's candidates; in ``tube`` mode they get their best
  result inside the tube (:func:`best_within`), so no method leaves the bound (and :func:`smooth`
  checks the exact two-sided distance of every bounded result before returning it);
* ``nacoa`` is :class:`toolpath.smoothing.nacoa.NACOA`; ``nacoa_permute`` the same with the paper's
  permuting initialisation;
* ``nacoa_matched`` is NACOA with ``cfg.head_to_head``'s smaller settings, run on the baseline windows;
  ``coa``, ``hba``, ``avoa``, ``scso``, ``esoa``, ``pso`` are mealpy's, given its charged budget of
  evaluations (computed from its settings: a gradient costs the 2 evaluations per coordinate of
  Eq. 23, however it is computed), its first population and the same seed.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import replace

import numpy as np

from toolpath.geometry.hausdorff import hausdorff
from toolpath.smoothing import tube
from toolpath.smoothing.mealpy_runs import MEALPY_CLASSES, encoding_shift, run_mealpy
from toolpath.smoothing.nacoa import NACOA, NACOASettings, initial_population
from toolpath.smoothing.problem import BOUNDED, ProblemBatch, SmoothingProblem, clip_displacement
from toolpath.smoothing.result import SmoothingResult
from toolpath.smoothing.smoothers import bezier_fit, mean_filter

SMOOTHERS = ("mean_filter", "bezier")
# "nacoa_permute" is NACOA with the paper's initialisation as written (Sec. 4.2.1: interior points
# permuted), run beside the default to show what that does to a toolpath
METHODS = (*SMOOTHERS, "nacoa", "nacoa_permute", "nacoa_matched", *MEALPY_CLASSES)
BASELINE_ONLY = ("nacoa_permute", "nacoa_matched", *MEALPY_CLASSES)  # run on the baseline windows only
BLEND_STEPS = 20  # bisection steps of the largest blend a smoother's result admits in ``tube`` mode
ENCODINGS = ("plain", "shifted")
UNTOUCHED = "none"


def problem_from(window: np.ndarray, cfg: Mapping, mode: str) -> SmoothingProblem:
    return SmoothingProblem(window, mode=mode, tolerance=cfg["tolerance"], weight=cfg["penalty_weight"])


def nacoa_settings(cfg: Mapping, tolerance: float, matched: bool = False) -> NACOASettings:
    """NACOA's settings from the config (``matched``: with ``head_to_head``'s overrides); its random
    term and first population span the tolerance."""
    values = {k: v for k, v in cfg["nacoa"].items() if k != "_target_"}  # the config's class is NACOASettings
    if matched:
        values.update(cfg.get("head_to_head") or {})
    values.setdefault("perturbation", tolerance)
    return NACOASettings(**values)


def nacoa_budget(settings: NACOASettings, dimension: int) -> int:
    """Charged evaluations NACOA spends: first population, HBA phase, and G generations of one candidate
    plus one gradient each; a gradient costs ``2 x dimension`` (Eq. 23's central difference), whether
    it is computed that way or exactly."""
    per_gradient = 0 if settings.gradient == "off" else 2 * dimension
    n = settings.population
    return n * (1 + settings.hba_generations) + n * settings.generations * (1 + per_gradient)


def search_box(problem: SmoothingProblem, cfg: Mapping) -> float:
    """Half-width of the box mealpy searches per coordinate: the tolerance in ``bound`` mode (each
    point's disc is inside that box), ``cfg.box`` mm otherwise (in ``tube`` mode points slide)."""
    return problem.tolerance if problem.mode == "bound" else float(cfg["box"])


def smooth(window: np.ndarray, method: str, cfg: Mapping, mode: str, seed: int,
           encoding: str = "plain", check: bool = True) -> SmoothingResult:
    """Run ``method`` on one window under fidelity ``mode``; ``encoding`` applies to mealpy methods.
    ``check=False`` skips the two-sided check of ``bound`` mode, for a caller that measures the
    result itself (``toolpath smooth`` does, after rounding to the written precision)."""
    result = _run(window, method, cfg, mode, seed, encoding)
    if mode in BOUNDED and check:
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
    if method not in TOGETHER or len({len(w) for w in windows}) > 1 or (method == "mean_filter" and mode == "tube"):
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
        points, evaluations = best_within(problem, raw)
        return SmoothingResult(points=points, objective=float(problem.score(points)), evaluations=evaluations,
                               seconds=time.perf_counter() - began)
    if method in ("nacoa", "nacoa_matched", "nacoa_permute"):
        settings = nacoa_settings(cfg, problem.tolerance, matched=method == "nacoa_matched")
        return NACOA(replace(settings, init="permute") if method == "nacoa_permute" else settings).solve(problem, seed)
    settings = nacoa_settings(cfg, problem.tolerance, matched=True)
    box = search_box(problem, cfg)
    start = initial_population(problem, settings, np.random.default_rng(seed))
    shift = encoding_shift(problem, box, seed + 1) if encoding == "shifted" else None
    return run_mealpy(method, problem, population=settings.population, budget=nacoa_budget(settings, problem.dimension),
                      box=box, seed=seed, start=start, shift=shift)


def best_within(problem: SmoothingProblem, raw: np.ndarray) -> tuple[np.ndarray, int]:
    """A one-shot smoother's result ``raw`` brought inside the problem's bound, and the candidates it
    took.  ``bound``: projected onto the discs.  ``tube``: the lowest objective of three certified
    candidates: the disc projection, the tube repair of ``raw`` (when the matching certifies it) and
    the largest blend ``(1 - t) window + t raw`` that the matching certifies (bisection on t), so the
    smoother keeps as much of its own shape as the tolerance admits instead of a point-by-point clip."""
    if problem.mode != "tube":
        return problem.points(problem.displacement(raw)), 1
    window = problem.window
    discs = window.copy()
    discs[1:-1] += clip_displacement(raw[1:-1] - window[1:-1], problem.tolerance)
    candidates, evaluations = [discs], 2
    repaired = tube.repair(raw, window, problem.tolerance)
    if tube.feasible(repaired, window, problem.tolerance):
        candidates.append(repaired)
    low, high = 0.0, 1.0
    if tube.feasible(raw, window, problem.tolerance):
        low = 1.0
    else:
        for _ in range(BLEND_STEPS):
            mid = 0.5 * (low + high)
            evaluations += 1
            if tube.feasible(window + mid * (raw - window), window, problem.tolerance):
                low = mid
            else:
                high = mid
    candidates.append(window + low * (raw - window))
    scores = [float(problem.score(c)) for c in candidates]
    return candidates[int(np.argmin(scores))], evaluations + len(candidates)


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
