"""Local corner smoothing by NURBS (the NURBS corner paper, Sec. "Local corner smoothing", Eq. 6-8).

A corner of turning angle theta is drawn in its own frame (Fig. 2b, Fig. 4): the corner P_i at the
origin, the curve symmetric about the y axis, the legs going down-left and down-right, so
P_{i-1} = (-L sin phi, -L cos phi) and P_{i+1} = (L sin phi, -L cos phi) with phi = (pi - theta)/2,
and P_{i-2}, P_{i+2} at twice that distance.

* **Method 1**: the cubic NURBS on the five points P_{i-2}, P_{i-1}, P_i, P_{i+1}, P_{i+2}.
* **Method 2**: seven points, with P_{i+3} between P_{i-1} and P_i and its mirror P_{i+4} between
  P_i and P_{i+1}: P_{i-2}, P_{i-1}, P_{i+3}, P_i, P_{i+4}, P_{i+1}, P_{i+2}.

The curve is clamped, so it leaves the path at P_{i-2} and rejoins it at P_{i+2} along the legs.
Our reading of Eq. 7, where the text leaves it open:
- delta_2 is the distance from the curve's middle C(1/2) to the corner P_i;
- delta_1 is the largest distance from the curve to the original two legs;
- beyond Eq. 7, a transition must lie *inside* the corner (between the legs, on the side the path
  turns to), and its error is two-sided: the curve within delta_max of the legs and the legs (the
  corner point above all) within delta_max of the curve (:func:`two_sided_bound`);
- the last line of Eq. 7 sets delta_2 to ``delta_target`` (default delta_max) by solving for the
  weights, following the paper's main-control-point rule: if P_i has the largest N_k(1/2) w_k, then
  w_i = 1 and w_{i+3} = w_{i+4} = w is solved; otherwise w_{i+3} = w_{i+4} = 1 and w_i is solved
  (bisection; C(1/2) moves monotonically along the y axis with either weight).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np

from toolpath.corners.nurbs import Nurbs

SAMPLES = 401  # parameters at which curvature and deviation are evaluated


@dataclass(frozen=True)
class Corner:
    """A corner in its own frame: turning angle (rad) and leg length L (mm) to P_{i-1}, P_{i+1}."""

    turn: float
    leg: float

    @property
    def half_opening(self) -> float:
        return (math.pi - self.turn) / 2.0

    def leg_point(self, distance: float, side: int) -> np.ndarray:
        """The point at ``distance`` from the corner on the left (-1) or right (+1) leg."""
        phi = self.half_opening
        return np.array([side * distance * math.sin(phi), -distance * math.cos(phi)])

    def method1_points(self) -> np.ndarray:
        return np.array([self.leg_point(2 * self.leg, -1), self.leg_point(self.leg, -1), [0.0, 0.0],
                         self.leg_point(self.leg, 1), self.leg_point(2 * self.leg, 1)])

    def method2_points(self, extra: np.ndarray) -> np.ndarray:
        """The seven control points with P_{i+3} = ``extra`` (x < 0) and its mirror P_{i+4}."""
        mirror = np.array([-extra[0], extra[1]])
        p = self.method1_points()
        return np.array([p[0], p[1], extra, p[2], mirror, p[3], p[4]])

    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of P_{i+3} (Eq. 7): between P_{i-1} and P_i in x and in y."""
        p_prev = self.leg_point(self.leg, -1)
        return np.minimum(p_prev, 0.0), np.maximum(p_prev, 0.0)


def legs(corner: Corner) -> np.ndarray:
    """The corner the curve replaces: the polyline from the left leg's point at 2 L through the
    corner to the right leg's point at 2 L."""
    return np.array([corner.leg_point(2 * corner.leg, -1), [0.0, 0.0], corner.leg_point(2 * corner.leg, 1)])


def outside_distance(points: np.ndarray, corner: Corner) -> np.ndarray:
    """How far each point lies outside the corner's wedge (0 or negative inside it).  The wedge is
    bounded by the two leg lines; their outward normals are (-cos phi, sin phi) and (cos phi, sin phi)."""
    phi = corner.half_opening
    c, s = math.cos(phi), math.sin(phi)
    return np.maximum(-c * points[:, 0] + s * points[:, 1], c * points[:, 0] + s * points[:, 1])


def two_sided_bound(samples: np.ndarray, corner: Corner) -> float:
    """An upper bound of the two-sided distance between a sampled corner curve (running from the left
    leg at u = 0 to the right leg at u = 1) and its corner, cheap enough for every PSO candidate.

    Curve to legs: the largest sample distance (exact for a polyline inside the wedge whose middle
    sample lies on the bisector, as every symmetric curve here does: inside the wedge the distance
    to the legs is the smaller of two affine functions, so along a chord it peaks at an end or on
    the bisector).  Legs to curve: pair each sample of the first half with its foot on the left leg
    (the second half with the right leg); between two feet the leg stays within the larger of the
    two sample distances of the chord between them (interpolate both linearly), and the leg from the
    corner to the nearest foot stays within max(|c|, its distance) of that sample c (distance to a
    point is convex along a segment).  Within 1e-12 of :func:`toolpath.geometry.hausdorff`'s value
    for the curves of this module (tested)."""
    half = len(samples) // 2
    out = float(distance_to_legs(samples, corner).max())
    for side, part in ((-1, samples[:half + 1]), (1, samples[half:])):
        end = corner.leg_point(2 * corner.leg, side)
        s = np.clip(part @ end / (end @ end), 0.0, 1.0)
        e = np.linalg.norm(part - s[:, None] * end, axis=1)
        nearest = int(np.argmin(s))
        out = max(out, float(e.max()), float(np.linalg.norm(part[nearest])))
    return out


def distance_to_legs(points: np.ndarray, corner: Corner) -> np.ndarray:
    """Distance of each point to the nearer of the two legs (segments from the corner, length 2L)."""
    out = np.full(len(points), np.inf)
    for side in (-1, 1):
        end = corner.leg_point(2 * corner.leg, side)
        t = np.clip(points @ end / (end @ end), 0.0, 1.0)
        out = np.minimum(out, np.linalg.norm(points - t[:, None] * end, axis=1))
    return out


def _angle(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    """The angle abc at b (rad)."""
    u, v = a - b, c - b
    return math.acos(float(np.clip(u @ v / (np.linalg.norm(u) * np.linalg.norm(v) + 1e-300), -1.0, 1.0)))


def solve_weights(points: np.ndarray, delta_target: float) -> np.ndarray | None:
    """Weights of the seven control points that put C(1/2) at ``delta_target`` below P_i (the last
    line of Eq. 7, with the main-control-point rule of the module docstring); None if no positive
    weight does.  C(1/2) = sum N_k w_k P_k / sum N_k w_k is linear over linear in the free weight w,
    so y(w) = -delta_target has the closed-form root w = -(A + delta a) / (B + delta b)."""
    n = _basis_at_half(len(points))
    middle = len(points) // 2  # P_i: index 3 of method 2's seven points, 2 of method 1's five
    free = [middle]  # method 1 has no extra points: the corner's own weight is the one to solve
    if len(points) == 7:
        free = [2, 4] if np.argmax(n[[2, 3, 4]]) == 1 else [3]
    fixed = [k for k in range(len(points)) if k not in free]
    y = points[:, 1] - points[middle, 1]  # heights relative to the corner
    A, a = float(n[fixed] @ y[fixed]), float(n[fixed].sum())
    B, b = float(n[free] @ y[free]), float(n[free].sum())
    denominator = B + delta_target * b
    if abs(denominator) < 1e-15:
        return None
    w = -(A + delta_target * a) / denominator
    if not (1e-6 < w < 1e6):
        return None
    weights = np.ones(len(points))
    weights[free] = w
    return weights


@functools.lru_cache(maxsize=8)
def _basis_at_half(count: int) -> np.ndarray:
    """N_k(1/2) of a clamped uniform cubic with ``count`` control points (the knots never change)."""
    return Nurbs(np.zeros((count, 2)), np.ones(count)).basis(0.5)


@dataclass(frozen=True)
class CornerCurve:
    """A smoothed corner: its NURBS, peak curvature (1/mm), Eq. 7's delta_1 and delta_2, the bound of
    its two-sided error against the corner (mm), whether it lies inside the corner, and feasibility
    (Eq. 7 plus inside plus the two-sided error within delta_max)."""

    curve: Nurbs
    max_curvature: float
    delta_1: float
    delta_2: float
    error: float
    inside: bool
    feasible: bool


def judge(corner: Corner, curve: Nurbs, samples: np.ndarray, delta_2: float, delta_max: float) -> CornerCurve:
    """Peak curvature, errors, inside-ness and feasibility of any symmetric curve in the corner frame."""
    u = np.linspace(0.0, 1.0, len(samples))
    delta_1 = float(distance_to_legs(samples, corner).max())
    # a hair of slack for rounding: leg points themselves (the curve's ends) are on the boundary
    inside = bool(outside_distance(samples, corner).max() <= 1e-12 * max(1.0, corner.leg))
    error = two_sided_bound(samples, corner)
    feasible = (max(delta_1, delta_2, error) <= delta_max * (1 + 1e-9) and inside
                and bool(np.all(np.isfinite(samples))))
    return CornerCurve(curve, float(np.max(1.0 / curve.radius(u))), delta_1, delta_2, error, inside, feasible)


def evaluate(corner: Corner, points: np.ndarray, weights: np.ndarray, delta_max: float) -> CornerCurve:
    """Curvature and errors of a candidate, and whether it meets Eq. 7 (the box and angle rules
    apply to method 2, seven points)."""
    curve = Nurbs(points, weights)
    c = curve(np.linspace(0.0, 1.0, SAMPLES))
    judged = judge(corner, curve, c, float(np.linalg.norm(curve(0.5)[0] - points[len(points) // 2])), delta_max)
    feasible = judged.feasible
    if len(points) == 7:
        lo, hi = corner.box()
        extra = points[2]
        inside = bool(np.all(extra > lo) and np.all(extra < hi))
        apex = _angle(points[2], points[3], points[4])
        feasible = feasible and inside and _angle(points[0], points[1], points[2]) > apex \
            and _angle(points[1], points[2], points[3]) > apex
    return replace(judged, feasible=bool(feasible))


def method1(corner: Corner, delta_max: float) -> CornerCurve:
    """The five-point NURBS with unit weights."""
    return evaluate(corner, corner.method1_points(), np.ones(5), delta_max)


def method1_at(corner: Corner, delta_max: float) -> CornerCurve | None:
    """Method 1 held to the same delta_max as method 2: the five-point NURBS on the same legs with the
    corner's weight solved so that C(1/2) lies delta_max from P_i (the last line of Eq. 7).  This is
    what FDLS takes as input ("the five NURBS control points before smoothing"), so it is our reading
    of the paper's "before optimisation".  None when no positive weight does it."""
    points = corner.method1_points()
    weights = solve_weights(points, delta_max)
    return None if weights is None else evaluate(corner, points, weights, delta_max)
