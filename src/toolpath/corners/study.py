"""How large PSO must be: a convergence study over particles x iterations on drawn corners.

For each corner and each (particles, iterations) setting, PSO (Eq. 8) minimises the peak curvature
under Eq. 7 plus the inside and two-sided rules; each result is divided by the best any setting found
on that corner, so 1.0 means "as good as the biggest search" and the mean over corners shows where
more particles or iterations no longer help.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from toolpath.corners.curve import Corner
from toolpath.corners.pso import PsoSettings, pso_corner


def solve_grid(corner: Corner, delta_max: float, settings: PsoSettings, particles: list[int],
               iterations: list[int]) -> np.ndarray:
    """Peak curvature of PSO's answer for every (particles, iterations) pair (inf where none is found)."""
    out = np.full((len(particles), len(iterations)), math.inf)
    for a, p in enumerate(particles):
        for b, it in enumerate(iterations):
            found, _ = pso_corner(corner, delta_max, settings=replace(settings, particles=p, iterations=it))
            if found is not None:
                out[a, b] = found.max_curvature
    return out


def summarise_grid(grids: list[np.ndarray], particles: list[int], iterations: list[int],
                   enough: float = 0.01) -> dict:
    """Mean (and worst) peak curvature relative to each corner's best, per setting, and the cheapest
    setting (fewest evaluations) whose mean is within ``enough`` of the best."""
    solved = [g for g in grids if np.isfinite(g).any()]
    relative = np.array([g / g[np.isfinite(g)].min() for g in solved]) if solved else np.zeros((0, 1, 1))
    mean = relative.mean(axis=0) if solved else np.full((len(particles), len(iterations)), math.nan)
    worst = relative.max(axis=0) if solved else mean
    table = [{"particles": p, "iterations": it, "evaluations": p * (it + 1),
              "mean_relative_curvature": float(mean[a, b]), "worst_relative_curvature": float(worst[a, b])}
             for a, p in enumerate(particles) for b, it in enumerate(iterations)]
    good = [r for r in table if r["mean_relative_curvature"] <= 1.0 + enough]
    cheapest = min(good, key=lambda r: (r["evaluations"], r["particles"])) if good else None
    return {"corners": len(grids), "solved": len(solved), "settings": table, "enough": enough,
            "cheapest_within_enough": cheapest}
