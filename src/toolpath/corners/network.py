"""FDLS / SDLS (the NURBS corner paper, Figs. 6-7): Double-ResNet surrogates of the PSO corner solver.

* **FDLS** takes the five control points of method 1 (10 numbers, mm, in the corner's frame) and
  predicts the extra point P_{i+3} (its mirror P_{i+4} follows by symmetry).
* **SDLS** takes the seven control points of method 2 (14 numbers) and predicts the log-weights.

Each is a stack of 64 fully connected layers with a shortcut every 8 (``ResidualMLP``) and
dropout, trained with MSE and Adam (FDLS: batch 16, lr 0.005; SDLS: batch 64, lr 0.001) on corners
that PSO solved.  A prediction is checked against Eq. 7, the inside-the-corner rule and the
two-sided error: an answer that misses is repaired (the extra point projected into Eq. 7's box and
into the corner's wedge, the weights from the closed-form rule), and a corner that still fails goes
back to PSO,
so :func:`smooth_corner` never returns an infeasible corner.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
import torch
from torch import nn

from toolpath.corners.curve import Corner, CornerCurve, evaluate, solve_weights
from toolpath.corners.pso import PsoSettings, pso_corner

REPAIR_TARGETS = tuple(np.linspace(1.0, 0.5, 11))  # fractions of delta_max tried by the weight repair


class ResidualMLP(nn.Module):
    """``layers`` Linear+ReLU layers of ``width`` with an identity shortcut around every ``every`` of
    them, dropout after each block, and linear input and output layers."""

    def __init__(self, inputs: int, outputs: int, width: int = 64, layers: int = 64, every: int = 8,
                 dropout: float = 0.1) -> None:
        super().__init__()
        if layers % every:
            raise ValueError(f"layers ({layers}) must be a multiple of the shortcut spacing ({every})")
        self.head = nn.Linear(inputs, width)
        self.blocks = nn.ModuleList(
            nn.Sequential(*[m for _ in range(every) for m in (nn.Linear(width, width), nn.ReLU())])
            for _ in range(layers // every))
        self.dropout = nn.Dropout(dropout)
        self.tail = nn.Linear(width, outputs)
        for block in self.blocks:  # residual branches start small, so the deep stack trains from the start
            nn.init.zeros_(block[-2].weight)
            nn.init.zeros_(block[-2].bias)
        # inputs and outputs are standardised inside the network (set by :func:`fit`, saved with it):
        # corner coordinates span a few mm while the answer must be right to a fraction of delta_max
        for name, size in (("x_mean", inputs), ("x_scale", inputs), ("y_mean", outputs), ("y_scale", outputs)):
            self.register_buffer(name, torch.zeros(size) if name.endswith("mean") else torch.ones(size))

    def standardised(self, x: torch.Tensor) -> torch.Tensor:
        """The output in standard units (what the loss compares)."""
        h = torch.relu(self.head((x - self.x_mean) / self.x_scale))
        for block in self.blocks:
            h = self.dropout(h + block(h))
        return self.tail(h)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.standardised(x) * self.y_scale + self.y_mean

    def set_scales(self, X: torch.Tensor, Y: torch.Tensor) -> None:
        for name, data in (("x", X), ("y", Y)):
            getattr(self, f"{name}_mean").copy_(data.mean(dim=0))
            getattr(self, f"{name}_scale").copy_(data.std(dim=0).clamp_min(1e-8) if len(data) > 1
                                                 else torch.ones(data.shape[1]))


@dataclass(frozen=True)
class CornerSample:
    """One corner PSO solved: its method-1 points, the extra point and the weights."""

    corner: Corner
    method1: np.ndarray   # (5, 2)
    points: np.ndarray    # (7, 2)
    weights: np.ndarray   # (7,)


def draw_corners(count: int, seed: int, turns: tuple[float, float] = (math.radians(30), math.radians(150)),
                 legs: tuple[float, float] = (0.5, 3.0)) -> list[tuple[Corner, int]]:
    """``count`` corners drawn uniformly in turn (rad) and leg (mm), each with its own PSO seed."""
    rng = np.random.default_rng(seed)
    return [(Corner(turn=float(rng.uniform(*turns)), leg=float(rng.uniform(*legs))), int(rng.integers(2**31)))
            for _ in range(count)]


def solve(corner: Corner, seed: int, delta_max: float, settings: PsoSettings) -> tuple[CornerSample | None, float]:
    """PSO's solution of one corner (None when it finds no feasible one) and the seconds it took."""
    started = time.perf_counter()
    best, _ = pso_corner(corner, delta_max, settings=PsoSettings(**{**settings.__dict__, "seed": seed}))
    seconds = time.perf_counter() - started
    if best is None:
        return None, seconds
    return CornerSample(corner, corner.method1_points(), best.curve.points, best.curve.weights), seconds


def solved_corners(count: int, delta_max: float, seed: int, settings: PsoSettings,
                   turns: tuple[float, float] = (math.radians(30), math.radians(150)),
                   legs: tuple[float, float] = (0.5, 3.0)) -> list[CornerSample]:
    """The PSO solutions of ``count`` drawn corners (those PSO cannot solve under Eq. 7 are left out)."""
    found = (solve(corner, s, delta_max, settings)[0] for corner, s in draw_corners(count, seed, turns, legs))
    return [sample for sample in found if sample is not None]


def held_inside(sample: CornerSample, delta_max: float, delta_margin: float, wedge_margin: float,
                limit: float = math.inf) -> CornerSample:
    """A training target held inside the checks: PSO's optimum sits on Eq. 7's boundary (C(1/2) at
    delta_max, the curve grazing the incoming leg), so an answer a network gets right to 2 % misses it
    about as often as it meets it.  The extra point moved ``wedge_margin`` x L into the corner and the
    weights re-solved for C(1/2) at (1 - ``delta_margin``) delta_max; PSO's own answer where that moved
    curve fails a check or is at least ``limit`` sharp (Eq. 7's cur_max)."""
    if delta_margin == 0 and wedge_margin == 0:
        return sample
    corner, phi = sample.corner, sample.corner.half_opening
    outward = np.array([-math.cos(phi), math.sin(phi)])  # the incoming leg's outward normal
    points = corner.method2_points(sample.points[2] - wedge_margin * corner.leg * outward)
    weights = solve_weights(points, (1.0 - delta_margin) * delta_max)
    if weights is None:
        return sample
    found = evaluate(corner, points, weights, delta_max)
    return replace(sample, points=points, weights=weights) if found.feasible and found.max_curvature < limit \
        else sample


def fit(net: nn.Module, X: np.ndarray, Y: np.ndarray, epochs: int, batch: int, lr: float, seed: int
        ) -> list[float]:
    """MSE of the standardised outputs and Adam, shuffled with ``seed``; the loss of each epoch (Figs. 8-9)."""
    torch.manual_seed(seed)
    generator = torch.Generator().manual_seed(seed)
    X_t, Y_t = torch.as_tensor(X, dtype=torch.float32), torch.as_tensor(Y, dtype=torch.float32)
    if isinstance(net, ResidualMLP):
        net.set_scales(X_t, Y_t)
        Z_t = (Y_t - net.y_mean) / net.y_scale
    else:
        Z_t = Y_t
    # foreach: one kernel per step for all of the deep stack's parameters, the same numbers as the per-parameter loop
    optimiser = torch.optim.Adam(net.parameters(), lr=lr, foreach=True)
    curve = []
    for _ in range(epochs):
        net.train()
        order = torch.randperm(len(X_t), generator=generator)
        total = 0.0
        for start in range(0, len(order), batch):
            idx = order[start:start + batch]
            optimiser.zero_grad()
            out = net.standardised(X_t[idx]) if isinstance(net, ResidualMLP) else net(X_t[idx])
            loss = nn.functional.mse_loss(out, Z_t[idx])
            loss.backward()
            optimiser.step()
            total += float(loss.detach()) * len(idx)
        curve.append(total / len(X_t))
    net.eval()
    return curve


def fdls_data(samples: list[CornerSample]) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([s.method1.ravel() for s in samples]), np.array([s.points[2] for s in samples]))


def sdls_data(samples: list[CornerSample]) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([s.points.ravel() for s in samples]), np.log(np.array([s.weights for s in samples])))


def predict(fdls: nn.Module, sdls: nn.Module, corner: Corner) -> tuple[np.ndarray, np.ndarray]:
    """The seven control points and weights the two networks give for ``corner``."""
    with torch.no_grad():
        x = torch.as_tensor(corner.method1_points().ravel()[None], dtype=torch.float32)
        extra = fdls(x)[0].double().numpy()
        points = corner.method2_points(extra)
        log_w = sdls(torch.as_tensor(points.ravel()[None], dtype=torch.float32))[0].double().numpy()
    return points, np.exp(log_w)


def _into_box_and_wedge(corner: Corner, extra: np.ndarray) -> np.ndarray:
    """The extra point moved into Eq. 7's box and onto the inner side of the incoming leg's line
    (a control point outside the wedge pulls the curve outside the corner)."""
    lo, hi = corner.box()
    margin = 1e-3 * (hi - lo)
    extra = np.clip(extra, lo + margin, hi - margin)
    phi = corner.half_opening
    outward = np.array([-math.cos(phi), math.sin(phi)])  # the incoming leg's outward normal
    excess = float(extra @ outward) + 1e-3 * corner.leg
    if excess > 0:
        extra = np.clip(extra - excess * outward, lo + margin, hi - margin)
    return extra


def smooth_corner(fdls: nn.Module, sdls: nn.Module, corner: Corner, delta_max: float,
                  settings: PsoSettings, curvature_limit: float = math.inf) -> tuple[CornerCurve | None, str]:
    """The networks' corner if it meets Eq. 7 and lies inside the corner within the two-sided error
    ('net'), else repaired ('repaired': the extra point projected into the box and the wedge, the
    weights by the closed-form rule for C(1/2) at delta_max or, if
    delta_1 still exceeds it, a little closer to the corner), else
    PSO's ('pso'); (None, 'infeasible') only when PSO finds no feasible corner either.

    ``curvature_limit`` is Eq. 7's cur_max for the networks' answers: a net or repaired curve at
    least that sharp (a repair can pinch the curve) goes back to PSO, which minimises the curvature."""
    points, weights = predict(fdls, sdls, corner)
    found = evaluate(corner, points, weights, delta_max)
    if found.feasible and found.max_curvature < curvature_limit:
        return found, "net"
    points = corner.method2_points(_into_box_and_wedge(corner, points[2]))
    # the closed-form weights put C(1/2) at delta_max; where another error then overshoots, lower
    # that target step by step (REPAIR_TARGETS of delta_max) until the checks hold
    for fraction in REPAIR_TARGETS:
        repaired = solve_weights(points, fraction * delta_max)
        if repaired is not None:
            found = evaluate(corner, points, repaired, delta_max)
            if found.feasible and found.max_curvature < curvature_limit:
                return found, "repaired"
    best, _ = pso_corner(corner, delta_max, settings=settings)
    return (best, "pso") if best is not None else (None, "infeasible")
