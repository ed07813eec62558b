"""Smooth every local corner of a G01 path with one corner method, and sample the result for the
feedrate planner (the NURBS corner paper, Sec. "Local corner smoothing" applied to a whole path; issue 9).

A vertex is a local corner when the path turns there by at least ``min_turn`` (smaller turns, such
as the chords of an arc, are left to the controller's blend).  Each corner gets the room
``min(l_in, l_out) / 2`` along both legs, so neighbouring transitions never overlap, capped by
``max_leg`` (the NURBS's farthest control point lies at 2 L <= 2 max_leg from the corner; FDLS /
SDLS learn corners up to that leg).  The methods:

* ``nurbs_pso`` — method 2 by PSO (Eq. 7-8); ``nurbs_net`` — FDLS / SDLS, checked, repaired or
  handed back to PSO (an answer sharper than method 1 at the same delta_max goes back too);
  ``bspline`` and ``bezier`` — the comparison transitions of :mod:`toolpath.corners.transitions`;
* a corner no method can smooth under Eq. 7 (or a near reversal) stays a sharp vertex, planned with
  the controller blend radius of :func:`toolpath.feedrate.polyline_radius`, and is reported.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from toolpath.corners.curve import SAMPLES, Corner, CornerCurve, legs, method1_at
from toolpath.corners.pso import PsoSettings, pso_corner
from toolpath.corners.transitions import bezier_transition, bspline_transition
from toolpath.feedrate.limits import polyline_radius
from toolpath.geometry.hausdorff import hausdorff

CORNER_METHODS = ("nurbs_pso", "nurbs_net", "bspline", "bezier")
MAX_TURN = math.radians(175.0)  # beyond this a corner is a reversal: the tool stops there


@dataclass(frozen=True)
class CornerSettings:
    """How corners are found and held: Eq. 7's delta_max, the smallest turn that counts as a
    corner, the longest leg L, the controller blend tolerance for sharp vertices, samples per curve
    and the spacing of samples along straight runs (mm)."""

    delta_max: float = 0.1
    min_turn_deg: float = 15.0
    max_leg: float = 3.0
    blend_tolerance: float = 0.005
    curve_samples: int = 101
    line_step: float = 0.1
    pso: PsoSettings = PsoSettings()


@dataclass(frozen=True)
class CornerResult:
    """One corner of a path: its vertex, turn, leg L, two 'before' curvatures, the method's peak
    curvature, its exact two-sided error against the corner it replaces, whether it lies inside the
    corner, where the answer came from, and time.

    The sharp G01 corner itself has infinite curvature and the paper does not say what its 'before'
    is, so there are two: ``curvature_before``, the circular blend a controller would run within the
    same delta_max (the largest arc within delta_max of the vertex and within half of each segment,
    :func:`toolpath.feedrate.polyline_radius`), the physical reference; and ``curvature_method1``,
    method 1's five-point NURBS on the same legs held to the same delta_max
    (:func:`toolpath.corners.curve.method1_at`), what FDLS takes as "before smoothing"."""

    vertex: int
    turn_deg: float
    leg: float
    curvature_before: float
    curvature_method1: float
    curvature_after: float
    error: float
    inside: bool
    source: str
    seconds: float

    @property
    def reduction_pct(self) -> float:
        """Peak-curvature reduction against the circular blend."""
        return 100.0 * (1.0 - self.curvature_after / self.curvature_before)

    @property
    def reduction_vs_method1_pct(self) -> float:
        """Peak-curvature reduction against method 1 at the same delta_max (NaN where it has none)."""
        return 100.0 * (1.0 - self.curvature_after / self.curvature_method1)


@dataclass(frozen=True)
class SmoothedPath:
    """Samples of the smoothed path (M, 2), their radius of curvature (M,), and the corners."""

    points: np.ndarray
    rho: np.ndarray
    corners: tuple[CornerResult, ...]


# (corner, settings, cur_max for a surrogate's answer) -> (curve or None, source)
Smoother = Callable[[Corner, CornerSettings, float], tuple[CornerCurve | None, str]]


def surrogate_limit(corner: Corner, delta_max: float) -> float:
    """Eq. 7's cur_max for the surrogates' answers: the peak curvature of method 1 at the same delta_max
    (the curve FDLS starts from), so a network answer must improve on it or go back to PSO.  (The
    circular blend cannot serve: no G2 curve inside the corner within delta_max is as flat as the arc,
    so every answer would go back.)"""
    reference = method1_at(corner, delta_max)
    return reference.max_curvature if reference is not None and reference.feasible else math.inf


def surrogate_corner(nets: tuple, corner: Corner, delta_max: float, pso: PsoSettings,
                     limit: float) -> tuple[CornerCurve | None, str]:
    """FDLS / SDLS's corner, checked against ``limit`` (Eq. 7's cur_max, :func:`surrogate_limit`): a
    sharper answer goes back to PSO.  Where there is no reference to beat (method 1 cannot be held to
    delta_max), a repair can pinch the curve into a near cusp that Eq. 7 alone accepts, so the networks
    are not trusted there and PSO decides."""
    from toolpath.corners.network import smooth_corner

    if not math.isfinite(limit):
        found, _ = pso_corner(corner, delta_max, settings=pso)
        return (found, "pso") if found is not None else (None, "infeasible")
    return smooth_corner(nets[0], nets[1], corner, delta_max, pso, limit)


def pso_smoother(corner: Corner, settings: CornerSettings, _: float = math.inf) -> tuple[CornerCurve | None, str]:
    """Method 2 by PSO with method 1 at delta_max and the dual Bezier on the same room in its first swarm
    (:func:`toolpath.corners.pso.pso_corner`'s references): never sharper than either where either is
    feasible.  The source says which family the answer is: ``pso``, ``pso: method 1`` or ``pso: dual Bezier``."""
    references = {"pso: method 1": method1_at(corner, settings.delta_max),
                  "pso: dual Bezier": bezier_transition(corner.turn, 2 * corner.leg, settings.delta_max)}
    found, _ = pso_corner(corner, settings.delta_max, settings=settings.pso, references=list(references.values()))
    return found, next((name for name, curve in references.items() if found is curve and found is not None), "pso")


def corner_smoother(method: str, nets: tuple | None = None) -> Smoother:
    """The corner function of ``method``; ``nurbs_net`` needs ``nets`` = (fdls, sdls)."""
    if method == "nurbs_pso":
        return pso_smoother
    if method == "nurbs_net":
        if nets is None:
            raise ValueError("nurbs_net needs the trained FDLS and SDLS networks")

        return lambda corner, s, limit: surrogate_corner(nets, corner, s.delta_max, s.pso, limit)
    if method == "bspline":
        return lambda corner, s, _: (bspline_transition(corner.turn, 2 * corner.leg, s.delta_max), "closed-form")
    if method == "bezier":
        return lambda corner, s, _: (bezier_transition(corner.turn, 2 * corner.leg, s.delta_max), "search")
    raise ValueError(f"unknown corner method {method!r}; known: {', '.join(CORNER_METHODS)}")


def corner_error(found: CornerCurve, turn: float) -> float:
    """The exact two-sided distance between a corner curve (sampled as Eq. 7 is checked) and the two
    legs it replaces (from where the curve leaves the path to where it rejoins it)."""
    samples = found.curve(np.linspace(0.0, 1.0, SAMPLES))
    return float(hausdorff(samples, legs(Corner(turn, float(np.linalg.norm(samples[0])) / 2.0))))


def arc_blend_curvature(corner: Corner, delta_max: float) -> float:
    """Curvature of the circular blend within ``delta_max`` of a corner whose two segments are 4 L long
    (the 'before' of :class:`CornerResult`, for a corner seen alone)."""
    legs = np.array([corner.leg_point(4 * corner.leg, -1), [0.0, 0.0], corner.leg_point(4 * corner.leg, 1)])
    return float(1.0 / polyline_radius(legs, delta_max)[1])


def corner_frames(points: np.ndarray, settings: CornerSettings) -> list[tuple[int, Corner, np.ndarray]]:
    """(vertex, corner, frame-to-world matrix) of every local corner.  The matrix's columns are the
    bisector e_x = (a + b)/|a + b| and e_y = (a - b)/|a - b| of the unit legs a (in) and b (out), so
    the frame's incoming leg direction (sin phi, cos phi) maps onto a and the outgoing onto b."""
    seg = np.diff(points, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    out = []
    for i in range(1, len(points) - 1):
        if length[i - 1] <= 0 or length[i] <= 0:
            continue
        a, b = seg[i - 1] / length[i - 1], seg[i] / length[i]
        turn = math.acos(float(np.clip(a @ b, -1.0, 1.0)))
        if turn < math.radians(settings.min_turn_deg):
            continue
        leg = min(min(length[i - 1], length[i]) / 4.0, settings.max_leg)
        frame = np.column_stack([(a + b) / max(np.linalg.norm(a + b), 1e-300), (a - b) / np.linalg.norm(a - b)])
        out.append((i, Corner(turn, leg), frame))
    return out


def _line(start: np.ndarray, end: np.ndarray, step: float) -> np.ndarray:
    """Points strictly between ``start`` and ``end``, at most ``step`` apart."""
    count = int(np.ceil(np.linalg.norm(end - start) / step))
    t = np.linspace(0.0, 1.0, count + 1)[1:-1]
    return start + t[:, None] * (end - start)


def smooth_path(points: np.ndarray, smoother: Smoother, settings: CornerSettings) -> SmoothedPath:
    """Replace every local corner by the smoother's curve and sample the whole path."""
    points = np.asarray(points, dtype=float)
    blend = polyline_radius(points, settings.blend_tolerance)
    within_delta = polyline_radius(points, settings.delta_max)
    curves: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    results = []
    for vertex, corner, frame in corner_frames(points, settings):
        before = 1.0 / within_delta[vertex]
        limit = surrogate_limit(corner, settings.delta_max)
        method1 = limit if math.isfinite(limit) else math.nan
        started = time.perf_counter()
        found, source = (None, "reversal") if corner.turn > MAX_TURN else smoother(corner, settings, limit)
        seconds = time.perf_counter() - started
        if found is None or not found.feasible:
            reason = (f"kept: reversal (turn over {math.degrees(MAX_TURN):.0f} deg)" if source == "reversal" else
                      f"kept: no curve meets Eq. 7 within delta_max on legs of {corner.leg:.3f} mm")
            results.append(CornerResult(vertex, math.degrees(corner.turn), corner.leg, before, method1,
                                        1.0 / blend[vertex], math.nan, False, reason, seconds))
            continue
        u = np.linspace(0.0, 1.0, settings.curve_samples)
        curves[vertex] = (points[vertex] + found.curve(u) @ frame.T, found.curve.radius(u))
        results.append(CornerResult(vertex, math.degrees(corner.turn), corner.leg, before, method1,
                                    found.max_curvature, corner_error(found, corner.turn), found.inside, source,
                                    seconds))
    xy, rho = [points[:1]], [np.array([np.inf])]
    last = points[0]
    for i in range(1, len(points)):
        entry = curves[i][0][0] if i in curves else points[i]
        xy.append(_line(last, entry, settings.line_step))
        rho.append(np.full(len(xy[-1]), np.inf))
        if i in curves:
            xy.append(curves[i][0])
            rho.append(curves[i][1])
            last = curves[i][0][-1]
        else:
            xy.append(points[i:i + 1])
            rho.append(blend[i:i + 1])
            last = points[i]
    return SmoothedPath(np.vstack(xy), np.concatenate(rho), tuple(results))
