"""Two established corner transitions that stand in for the NURBS corner paper's refs. 20-21 (issue 9), both held to
the same maximum approximation error delta_max and the same room along the legs as the NURBS of
:mod:`toolpath.corners.curve`, in the same corner frame (corner at the origin, legs going down).

* :func:`bspline_transition` — the symmetric cubic B-spline transition of Zhao, Zhu and Ding,
  "A real-time look-ahead interpolation methodology with curvature-continuous B-spline transition
  scheme for CNC machining of short line segments", Int. J. Mach. Tools Manuf. 65 (2013) 88-98:
  five control points P_{i-2}, P_{i-1}, P_i, P_{i+1}, P_{i+2} (the NURBS corner paper's method 1, unit weights),
  with the leg length L chosen in closed form so that the largest deviation is delta_max (every
  deviation of this curve is proportional to L), or the room on the legs when that is shorter.
* :func:`bezier_transition` — a G2-continuous dual cubic Bezier transition, after Bi, Shi, Wang, Zhu
  and Ding, "Analytical curvature-continuous dual-Bezier corner transition for five-axis linear
  tool path", Int. J. Mach. Tools Manuf. 91 (2015) 96-108, in the plane: two cubic Bezier curves
  B0..B3 and their mirror, B0, B1, B2 on the incoming leg (zero curvature where the line ends, so
  G2 there), B3 on the bisector with B2B3 perpendicular to it (so the two halves meet with equal
  tangent and, by symmetry, equal curvature).  B0 = Q(d), B1 = Q(d (1 + k) / 2), B2 = Q(k d), with
  Q(r) the leg point at distance r; the apex B3 is the curve's point nearest the corner, so
  d = delta_max / (k cos phi) (or the room on the legs).  Bi et al. give k analytically for their
  curvature objective; we pick k by a bounded scalar search minimising the peak curvature.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar

from toolpath.corners.curve import SAMPLES, Corner, CornerCurve, evaluate, judge
from toolpath.corners.nurbs import Nurbs

DUAL_BEZIER_KNOTS = (0.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.5, 1.0, 1.0, 1.0, 1.0)


def bspline_transition(turn: float, room: float, delta_max: float) -> CornerCurve:
    """Zhao et al. (2013): the five-point cubic B-spline whose farthest control point lies at
    min(room, the distance that makes the largest deviation delta_max) from the corner."""
    unit = evaluate(Corner(turn, 1.0), Corner(turn, 1.0).method1_points(), np.ones(5), math.inf)
    per_leg = max(unit.delta_1, unit.delta_2, unit.error)  # every deviation scales with the leg length
    leg = min(room / 2.0, delta_max / per_leg)
    corner = Corner(turn, leg)
    return evaluate(corner, corner.method1_points(), np.ones(5), delta_max)


def _dual_bezier(turn: float, span: float, ratio: float) -> tuple[Corner, np.ndarray]:
    corner = Corner(turn, span / 2.0)  # its legs reach 2L = span
    b0, b1, b2 = (corner.leg_point(r, -1) for r in (span, span * (1 + ratio) / 2, span * ratio))
    apex = np.array([0.0, b2[1]])
    mirror = np.array([-1.0, 1.0])
    return corner, np.array([b0, b1, b2, apex, b2 * mirror, b1 * mirror, b0 * mirror])


def bezier_curve(turn: float, span: float, ratio: float, delta_max: float) -> CornerCurve:
    """The dual cubic Bezier with its ends ``span`` from the corner and B2 at ``ratio`` of it."""
    corner, points = _dual_bezier(turn, span, ratio)
    return evaluate_curve(corner, Nurbs(points, np.ones(7), 3, DUAL_BEZIER_KNOTS), delta_max)


def evaluate_curve(corner: Corner, curve: Nurbs, delta_max: float) -> CornerCurve:
    """Peak curvature and deviations of any curve in the corner frame (no method-2 box rules)."""
    c = curve(np.linspace(0.0, 1.0, SAMPLES))
    return judge(corner, curve, c, float(np.linalg.norm(c, axis=1).min()), delta_max)  # the corner is the origin


def bezier_transition(turn: float, room: float, delta_max: float) -> CornerCurve:
    """Bi et al. (2015) in the plane, held to delta_max and ``room``; the ratio k of B2 minimises the
    peak curvature (bounded search on [0.05, 0.95])."""
    cos_phi = math.cos((math.pi - turn) / 2.0)

    def build(ratio: float) -> CornerCurve:
        return bezier_curve(turn, min(room, delta_max / (ratio * cos_phi)), ratio, delta_max)

    best = minimize_scalar(lambda k: build(k).max_curvature, bounds=(0.05, 0.95), method="bounded",
                           options={"xatol": 1e-4})
    return build(float(best.x))
