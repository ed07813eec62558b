"""NACOA, the novel adaptive coati optimisation algorithm of Li et al. (2024), Sec. 4.2 and Algorithm 2.

Four mechanisms on top of the coati algorithm, each vectorised over the whole population (numpy, no
Python loop over individuals):

1. honey-badger initialisation: intensity (Eq. 4), digging and foraging (Eq. 5), global best over
   generations (Eq. 11);
2. the adaptive update (Eq. 12) with ``alpha_2`` falling linearly (Eq. 13) and ``r7``, ``r8`` scaled
   by the fitness spread (Eq. 14);
3. dynamic sub-populations: ``N_g = N / M_g`` (Eq. 15), the schedule ``M_g`` (Eq. 16), sub-population
   and global bests (Eq. 17-18), an exchange every ``T`` generations (Eq. 19);
4. a gradient step with exponentially decaying rate (Eq. 25-27), exact or central-difference (Eq. 23).

Interpretations (the report lists them): the search runs on the problem's decision vector (interior
displacements from the original window), so Eq. 5's ``beta I g_best`` term is origin-free; ``d_i``
enters Eq. 5 as the vector ``g_best[i] - p_k[i]`` (its length is the paper's distance), with the
HBA paper's random sign; the intensity is capped at 1 and its ``d_i^2`` softened by ``tolerance^2``
so it stays finite at the global best; Eq. 12's random term is scaled by ``perturbation`` mm; each
sub-population follows its own best (Eq. 17) in Eq. 12; Eq. 25's rate ``eta(g)`` is in mm and each
point's gradient is normalised to unit length (``normalise: point``), because the curvature term's
gradient scales with one over the segment length, which spans orders of magnitude in a rough window
(a plain step either stalls on long segments or throws tiny ones off); and a move is kept only if it lowers the
objective (the coati algorithm's greedy rule).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from toolpath.smoothing.gradient import central_difference_gradient, fitness_gradient
from toolpath.smoothing.problem import ProblemBatch, SmoothingProblem, clip_displacement
from toolpath.smoothing.result import SmoothingResult

GRADIENTS = ("exact", "central", "off")
INITIALISATIONS = ("perturb", "permute")


@dataclass(frozen=True)
class NACOASettings:
    """Sec. 4.2.3's M0 = 10, M_min = 2, T = 10; the rest are ours (the paper gives no values)."""

    population: int = 100
    generations: int = 100
    hba_generations: int = 5
    alpha1: float = 2.0
    beta: float = 6.0
    alpha_max: float = 1.0
    alpha_min: float = 0.1
    m0: int = 10
    m_min: int = 2
    m_max: int = 10
    exchange_every: int = 10
    eta0: float = 0.01
    decay: float = 0.02
    gradient: str = "exact"
    eps: float = 1e-5
    init: str = "perturb"
    normalise: str = "point"
    perturbation: float = 0.05

    def __post_init__(self) -> None:
        if self.gradient not in GRADIENTS:
            raise ValueError(f"nacoa.gradient must be one of {GRADIENTS}, got {self.gradient!r}")
        if self.normalise not in ("point", "window", "none"):
            raise ValueError(f"nacoa.normalise must be point, window or none, got {self.normalise!r}")
        if self.init not in INITIALISATIONS:
            raise ValueError(f"nacoa.init must be one of {INITIALISATIONS}, got {self.init!r}")
        if not 1 <= self.m_min <= self.m0 <= self.m_max or self.m0 > self.population:
            raise ValueError("nacoa needs 1 <= m_min <= m0 <= m_max and m0 <= population")


def alpha2(g: int, generations: int, alpha_max: float, alpha_min: float) -> float:
    """Eq. 13: ``alpha_max - (alpha_max - alpha_min) g / G``."""
    return alpha_max - (alpha_max - alpha_min) * g / generations


def subpopulation_count(g: int, generations: int, m0: int, m_min: int, m_max: int) -> int:
    """Eq. 16: ``max(M_min, min(M_max, M_0 - floor(g (M_0 - M_min) / G)))``."""
    return max(m_min, min(m_max, m0 - math.floor(g * (m0 - m_min) / generations)))


def learning_rate(g: int, eta0: float, decay: float) -> float:
    """Eq. 26: ``eta_0 exp(-lambda g)``."""
    return eta0 * math.exp(-decay * g)


def subpopulation_of(population: int, count: int) -> np.ndarray:
    """Sub-population index of every individual: ``count`` contiguous blocks of ``N / M_g`` (Eq. 15)."""
    return (np.arange(population) * count) // population


def exchange(x: np.ndarray, fit: np.ndarray, groups: np.ndarray, rng: np.random.Generator) -> None:
    """Eq. 19: swap a random member of one random sub-population with one of another, in place.

    Sub-populations are index blocks, so swapping the two rows moves ``p_k`` into ``sub_pop_b`` and
    ``p_t`` into ``sub_pop_a``; every size stays the same.
    """
    count = int(groups.max()) + 1
    if count < 2:
        return
    a, b = rng.choice(count, size=2, replace=False)
    k = rng.choice(np.flatnonzero(groups == a))
    t = rng.choice(np.flatnonzero(groups == b))
    x[[k, t]] = x[[t, k]]
    fit[[k, t]] = fit[[t, k]]


def initial_population(problem: SmoothingProblem, settings: NACOASettings, rng: np.random.Generator) -> np.ndarray:
    """Decision vectors of the first population.

    ``perturb`` (default): the original window plus ``N - 1`` copies moved uniformly within
    ``perturbation`` mm per coordinate.  ``permute``: the paper as written (Sec. 4.2.1 a.ii): every
    individual's interior points are a random permutation of the original ones, which scrambles the
    order in which a toolpath visits them.
    """
    n_inner = len(problem.window) - 2
    if settings.init == "permute":
        order = np.argsort(rng.random((settings.population, n_inner)), axis=1)
        points = problem.window[1:-1][order]
        return (points - problem.window[1:-1]).reshape(settings.population, -1)
    x = rng.uniform(-settings.perturbation, settings.perturbation, (settings.population, problem.dimension))
    x[0] = 0.0
    return x


class NACOA:
    """Minimise a :class:`SmoothingProblem` from a seed; :meth:`solve` returns a :class:`SmoothingResult`.
    :meth:`solve_many` runs several windows side by side, each with its own seed: each result is the
    one :meth:`solve` gives (a test checks it bit for bit), at a fraction of the per-call overhead."""

    def __init__(self, settings: NACOASettings) -> None:
        self.settings = settings

    def _gradient(self, points: np.ndarray) -> tuple[np.ndarray, int]:
        """The gradient and its charged cost: Eq. 23's 2 evaluations per coordinate for either route
        (the exact one is cheaper to compute, not cheaper to charge: costs are charged alike)."""
        s = self.settings
        charged = 2 * (points.shape[-2] - 2) * 2
        if s.gradient == "exact":
            return fitness_gradient(points), charged
        if s.gradient == "central":
            return central_difference_gradient(points, s.eps), charged
        return np.zeros_like(points), 0

    def _evaluate(self, batch: ProblemBatch, x: np.ndarray,
                  incumbent: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Feasible decision vectors (projected in ``bound`` mode) and their objective values; with the
        ``incumbent`` values, exact only where they are lower (all the greedy rule compares)."""
        points = batch.points(x)
        return batch.displacement(points), batch.score(points, below=incumbent)

    def _honey_badger(self, batch: ProblemBatch, x, fit, rngs) -> tuple[np.ndarray, np.ndarray, int]:
        """Sec. 4.2.1: ``hba_generations`` of digging / foraging around the global best (Eq. 4-5, 11)."""
        s = self.settings
        count, pop, n_inner = x.shape[0], x.shape[1], batch.dimension // 2
        soft = max(batch.tolerance, 1e-9) ** 2
        evaluations = 0
        every = np.arange(count)
        for _ in range(s.hba_generations):
            best = x[every, fit.argmin(axis=1)].reshape(count, 1, n_inner, 2)
            pts = batch.points(x, project=False)  # x is feasible already
            xs = x.reshape(count, pop, n_inner, 2)
            # Eq. 4: S = |p_k[i+1] - p_k[i]|, d_i = |g_best[i] - p_k[i]|, I = r1 S / (4 pi d_i^2)
            seg = np.linalg.norm(pts[..., 2:, :] - pts[..., 1:-1, :], axis=-1)
            d_vec = best - xs
            d2 = np.sum(d_vec**2, axis=-1)
            draws = [(rng.random((pop, n_inner)), rng.choice([-1.0, 1.0], size=(pop, n_inner, 1)),
                      *(rng.random((pop, n_inner, 1)) for _ in range(5))) for rng in rngs]
            r1, sign, r2, r3, r4, r5, r6 = (np.stack(d) for d in zip(*draws, strict=True))
            intensity = np.minimum(r1 * seg / (4.0 * np.pi * (d2 + soft)), 1.0)
            # Eq. 5, digging (r6 <= 0.5) and foraging phases
            digging = (best + sign * s.beta * intensity[..., None] * best
                       + sign * r2 * s.alpha1 * d_vec * np.abs(np.cos(2 * np.pi * r3) * (1 - np.cos(2 * np.pi * r4))))
            foraging = best + sign * r5 * s.alpha1 * d_vec
            moved = np.where(r6 <= 0.5, digging, foraging).reshape(count, pop, -1)
            moved, moved_fit = self._evaluate(batch, moved, fit)
            evaluations += pop
            better = moved_fit < fit
            x[better], fit[better] = moved[better], moved_fit[better]  # Eq. 11 keeps the best over generations
        return x, fit, evaluations

    def solve(self, problem: SmoothingProblem, seed: int) -> SmoothingResult:
        return self.solve_many([problem], [seed])[0]

    def solve_many(self, problems: list[SmoothingProblem], seeds: list[int]) -> list[SmoothingResult]:
        """:meth:`solve` of each problem with its seed; the problems share window length, mode and tolerance."""
        s = self.settings
        start = time.perf_counter()
        batch, rngs = ProblemBatch(problems), [np.random.default_rng(seed) for seed in seeds]
        x = np.stack([initial_population(p, s, rng) for p, rng in zip(problems, rngs, strict=True)])
        if batch.mode == "tube":  # start inside the discs, which the tube contains: every start is certified
            x = clip_displacement(x.reshape(*x.shape[:-1], -1, 2), batch.tolerance).reshape(x.shape)
        x, fit = self._evaluate(batch, x)
        evaluations = x.shape[1]
        x, fit, used = self._honey_badger(batch, x, fit, rngs)
        evaluations += used
        history = []
        every = np.arange(len(problems))
        for g in range(1, s.generations + 1):
            m_g = subpopulation_count(g, s.generations, s.m0, s.m_min, s.m_max)  # Eq. 16
            groups = subpopulation_of(x.shape[1], m_g)  # Eq. 15
            # Eq. 17: best of every sub-population, the guide of its members in Eq. 12
            guide = np.empty_like(x)
            for a in range(m_g):
                members = groups == a
                guide[:, members] = x[:, members][every, fit[:, members].argmin(axis=1)][:, None]
            a2 = alpha2(g, s.generations, s.alpha_max, s.alpha_min)  # Eq. 13
            spread = 1.0 + fit.std(axis=1) / np.maximum(np.abs(fit.mean(axis=1)), 1e-12)  # Eq. 14
            draws = [(rng.random(x.shape[1:]), rng.random(x.shape[1:]), rng.random(x.shape[1:])) for rng in rngs]
            r7, r8, r9 = (np.stack(d) for d in zip(*draws, strict=True))
            r7, r8 = r7 * spread[:, None, None], r8 * spread[:, None, None]
            moved = x + a2 * r7 * (guide - x) + a2 * r8 * (r9 - 0.5) * s.perturbation  # Eq. 12
            # Eq. 25-27: one gradient step with the decaying rate of Eq. 26, then back into the feasible set
            pts = batch.points(moved, project=False)
            grad, cost = self._gradient(pts)
            if s.normalise == "point":
                scale = np.sqrt(grad[..., 0:1] ** 2 + grad[..., 1:2] ** 2)
            elif s.normalise == "window":
                scale = np.abs(grad).max(axis=(-2, -1), keepdims=True)
            else:
                scale = 1.0
            pts = pts - learning_rate(g, s.eta0, s.decay) * grad / np.maximum(scale, 1e-12)
            moved, moved_fit = self._evaluate(batch, batch.displacement(pts), fit)
            evaluations += x.shape[1] * (1 + cost)
            better = moved_fit < fit
            x[better], fit[better] = moved[better], moved_fit[better]
            if g % s.exchange_every == 0:
                for k, rng in enumerate(rngs):
                    exchange(x[k], fit[k], groups, rng)  # Eq. 19
            history.append(fit.min(axis=1))  # Eq. 18
        seconds = (time.perf_counter() - start) / len(problems)
        trail = np.array(history).T.tolist() if history else [[] for _ in problems]
        out = []
        for k, problem in enumerate(problems):
            best = int(fit[k].argmin())
            out.append(SmoothingResult(points=problem.points(x[k, best]), objective=float(fit[k, best]),
                                       evaluations=evaluations, seconds=seconds, history=trail[k]))
        return out
