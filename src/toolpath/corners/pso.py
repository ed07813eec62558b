"""Method 2's extra control points by PSO (the NURBS corner paper, Eq. 8), the whole swarm scored at once.

A particle is P_{i+3}; its seven control points, its weights (the closed form of
:func:`toolpath.corners.curve.solve_weights`), its curve, curvature and errors are exactly those of
:func:`toolpath.corners.curve.evaluate`, computed for every particle in one pass: the knots and the
sample parameters never change, so the B-spline basis and its derivatives are a fixed (samples x 7)
matrix and every curve is a matrix product (tested against the one-candidate route).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.stats import qmc

from toolpath.corners.curve import SAMPLES, Corner, CornerCurve, _basis_at_half, evaluate, solve_weights
from toolpath.corners.nurbs import clamped_uniform_knots

CONTROL_POINTS = 7


@dataclass(frozen=True)
class PsoSettings:
    """Eq. 8: inertia w, own-best c1, swarm-best c2 and the third term c3 (own best minus swarm best)."""

    particles: int = 24
    iterations: int = 40
    inertia: float = 0.7
    c1: float = 1.5
    c2: float = 1.5
    c3: float = 0.3
    seed: int = 0


@functools.lru_cache(maxsize=1)
def _design() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """N_k(u), N_k'(u), N_k''(u) at the SAMPLES parameters, and N_k(1/2): the basis of every candidate."""
    basis = BSpline(clamped_uniform_knots(CONTROL_POINTS, 3), np.eye(CONTROL_POINTS), 3)
    u = np.linspace(0.0, 1.0, SAMPLES)
    return basis(u), basis(u, 1), basis(u, 2), basis(np.array([0.5]))[0]


def _angles(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The angle abc at b (rad) per row, as :func:`toolpath.corners.curve._angle`."""
    u, v = a - b, c - b
    cos = np.einsum("pi,pi->p", u, v) / (np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1) + 1e-300)
    return np.arccos(np.clip(cos, -1.0, 1.0))


def _leg_errors(samples: np.ndarray, corner: Corner) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per particle: the largest distance to the legs (delta_1), the largest distance outside the
    wedge, and :func:`toolpath.corners.curve.two_sided_bound` of the sampled curves (P, S, 2)."""
    phi = corner.half_opening
    cos, sin = math.cos(phi), math.sin(phi)
    x, y = samples[..., 0], samples[..., 1]
    outside = np.maximum(-cos * x + sin * y, cos * x + sin * y).max(axis=1)
    to_legs = np.full(x.shape, np.inf)
    half = SAMPLES // 2
    bound = np.zeros(len(samples))
    for side in (-1, 1):
        end = corner.leg_point(2 * corner.leg, side)
        t = np.clip(samples @ end / (end @ end), 0.0, 1.0)
        to_legs = np.minimum(to_legs, np.linalg.norm(samples - t[..., None] * end, axis=2))
        part = samples[:, :half + 1] if side == -1 else samples[:, half:]
        s = t[:, :half + 1] if side == -1 else t[:, half:]
        e = np.linalg.norm(part - s[..., None] * end, axis=2)
        nearest = part[np.arange(len(part)), np.argmin(s, axis=1)]
        bound = np.maximum(bound, np.maximum(e.max(axis=1), np.linalg.norm(nearest, axis=1)))
    delta_1 = to_legs.max(axis=1)
    return delta_1, outside, np.maximum(bound, delta_1)


def swarm_fitness(corner: Corner, extras: np.ndarray, delta_max: float, delta_target: float,
                  curvature_limit: float = math.inf) -> np.ndarray:
    """Peak curvature of each particle's corner curve (1/mm), or inf where the candidate fails Eq. 7
    (with the inside and two-sided rules of :func:`toolpath.corners.curve.evaluate`) or reaches
    ``curvature_limit``.  ``extras`` is (P, 2): P_{i+3} of each particle."""
    d0, d1, d2, half = _design()
    base = corner.method1_points()
    count = len(extras)
    points = np.empty((count, CONTROL_POINTS, 2))
    points[:] = [base[0], base[1], base[2], base[2], base[2], base[3], base[4]]
    points[:, 2] = extras
    points[:, 4, 0], points[:, 4, 1] = -extras[:, 0], extras[:, 1]

    # solve_weights in closed form for every particle (the free weights depend on N(1/2) only)
    n = _basis_at_half(CONTROL_POINTS)
    free = [2, 4] if np.argmax(n[[2, 3, 4]]) == 1 else [3]
    fixed = [k for k in range(CONTROL_POINTS) if k not in free]
    y = points[:, :, 1] - points[:, 3:4, 1]
    denominator = y[:, free] @ n[free] + delta_target * n[free].sum()
    solvable = np.abs(denominator) >= 1e-15
    w = -(y[:, fixed] @ n[fixed] + delta_target * n[fixed].sum()) / np.where(solvable, denominator, 1.0)
    solvable &= (w > 1e-6) & (w < 1e6)
    weights = np.ones((count, CONTROL_POINTS))
    weights[:, free] = np.where(solvable, w, 1.0)[:, None]

    coef = np.concatenate([points * weights[..., None], weights[..., None]], axis=2)
    stacked = coef.transpose(1, 0, 2).reshape(CONTROL_POINTS, -1)  # one matrix product per basis
    h, h1, h2 = ((d @ stacked).reshape(SAMPLES, count, 3).transpose(1, 0, 2) for d in (d0, d1, d2))
    hw, hw1, hw2 = h[..., 2:], h1[..., 2:], h2[..., 2:]
    c = h[..., :2] / hw
    c1 = (h1[..., :2] - c * hw1) / hw
    c2 = (h2[..., :2] - 2 * c1 * hw1 - c * hw2) / hw
    cross = np.abs(c1[..., 0] * c2[..., 1] - c1[..., 1] * c2[..., 0])
    speed = np.hypot(c1[..., 0], c1[..., 1])
    curved = cross > 1e-15 * np.maximum(speed, 1e-300) ** 3
    with np.errstate(divide="ignore", invalid="ignore"):
        curvature = np.where(curved, cross / speed**3, 0.0).max(axis=1)
        middle = (half @ coef)  # C(1/2) in homogeneous coordinates
    delta_2 = np.hypot(middle[:, 0] / middle[:, 2], middle[:, 1] / middle[:, 2])

    delta_1, outside, error = _leg_errors(c, corner)
    inside = outside <= 1e-12 * max(1.0, corner.leg)
    feasible = (np.maximum(np.maximum(delta_1, delta_2), error) <= delta_max * (1 + 1e-9)) & inside
    feasible &= np.isfinite(c).all(axis=(1, 2))
    lo, hi = corner.box()
    feasible &= np.all((extras > lo) & (extras < hi), axis=1)
    apex = _angles(points[:, 2], points[:, 3], points[:, 4])
    feasible &= (_angles(points[:, 0], points[:, 1], points[:, 2]) > apex)
    feasible &= (_angles(points[:, 1], points[:, 2], points[:, 3]) > apex)
    ok = solvable & feasible & (curvature < curvature_limit)
    return np.where(ok, curvature, np.inf)


LEG_PARTICLES = 8


def leg_particles(corner: Corner, count: int) -> np.ndarray:
    """Method-1-like particles: P_{i+3} on the leg from P_{i-1} to P_i at fractions of L spaced
    geometrically from 0.01 to 0.95 of the way from the corner (the control polygon stays method 1's).
    The flattest curves of sharp corners sit on this diagonal within a few per cent of the corner,
    a basin too thin for a random start to find reliably."""
    return np.outer(np.geomspace(0.01, 0.95, count), corner.leg_point(corner.leg, -1))


def _candidate(corner: Corner, extra: np.ndarray, delta_max: float, delta_target: float) -> CornerCurve | None:
    points = corner.method2_points(extra)
    weights = solve_weights(points, delta_target)
    return None if weights is None else evaluate(corner, points, weights, delta_max)


def pso_corner(corner: Corner, delta_max: float = 0.1, delta_target: float | None = None,
               settings: PsoSettings = PsoSettings(), curvature_limit: float = math.inf,
               references: Sequence[CornerCurve] = ()) -> tuple[CornerCurve | None, list[float]]:
    """Method 2's extra points by PSO (Eq. 8) minimising the peak curvature under Eq. 7.

    Particles move in the open box of P_{i+3} (positions are kept strictly inside it), starting from a
    Latin hypercube of the box (a uniform draw can leave a whole basin of this two-mode
    landscape unvisited, and 48 particles then settle on the worse one); an infeasible candidate
    (including one whose peak curvature reaches ``curvature_limit``, Eq. 7's cur_max) has infinite
    fitness, so the answer, when there is one, is feasible.  ``references`` are curves of other
    families (method 1 at delta_max, the dual Bezier) that enter as the swarm's first best: a
    method-2 particle replaces one only by being flatter, so the answer is never sharper than a
    feasible reference; when one stays best it is returned itself (the caller can tell by identity).
    Returns the best corner (None if nothing met Eq. 7) and the best fitness per iteration.
    """
    target = delta_max if delta_target is None else delta_target
    lo, hi = corner.box()
    margin = 1e-6 * (hi - lo)
    lo, hi = lo + margin, hi - margin
    rng = np.random.default_rng(settings.seed)
    usable = [r for r in references if r is not None and r.feasible and r.max_curvature < curvature_limit]
    reference = min(usable, key=lambda r: r.max_curvature, default=None)
    floor = reference.max_curvature if reference is not None else math.inf

    def fitness(x: np.ndarray) -> np.ndarray:
        return swarm_fitness(corner, x, delta_max, target, curvature_limit)

    x = lo + qmc.LatinHypercube(d=2, seed=rng).random(settings.particles) * (hi - lo)
    x[:LEG_PARTICLES] = leg_particles(corner, min(LEG_PARTICLES, settings.particles))
    v = np.zeros_like(x)
    best_x, best_f = x.copy(), fitness(x)
    g = int(np.argmin(best_f))
    history = [float(best_f[g])]
    for _ in range(settings.iterations):
        r1, r2, r3 = rng.random((3, *x.shape))
        gbest = best_x[g]
        v = (settings.inertia * v + settings.c1 * r1 * (best_x - x) + settings.c2 * r2 * (gbest - x)
             + settings.c3 * r3 * (best_x - gbest))
        x = np.clip(x + v, lo, hi)
        f = fitness(x)
        better = f < best_f
        best_x[better], best_f[better] = x[better], f[better]
        g = int(np.argmin(best_f))
        history.append(float(best_f[g]))
    history = [min(h, floor) for h in history]
    if not best_f[g] < floor:
        return reference, history
    return _candidate(corner, best_x[g], delta_max, target), history
