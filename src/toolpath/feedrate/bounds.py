"""Two machining times that bracket the planner's (issue 9): a time-optimal lower bound without a jerk
limit (toppra) and an upper bound that stops at every vertex.

The lower bound solves the time-optimal path parametrisation along the arc length s, a one-axis
path q(s) = s, under the speed limit v_f(s) of Eq. 22 (which already holds chord error, contour
error, normal acceleration and normal jerk) and the tangential acceleration limit; it has no
tangential jerk limit, so any plan meeting the same limits and a jerk limit takes at least as long.
"""

from __future__ import annotations

import numpy as np

from toolpath.feedrate.limits import Machine, feed_limit
from toolpath.feedrate.planner import arc_length
from toolpath.feedrate.scurve import ramp_distance, ramp_time


def toppra_time(points: np.ndarray, rho: np.ndarray, machine: Machine, straight: bool = True,
                steps: int = 2000) -> float:
    """Lower bound (s): TOPP-RA along ``points`` with v <= v_f(s) and |a_t| <= A, rest at both ends.

    ``straight``: a G01 path, whose limits bind at its vertices (the segments run up to the feed);
    otherwise the limit is interpolated between points sampled on a smooth curve.  The grid holds
    every vertex and at least ``steps`` points.
    """
    import toppra
    import toppra.algorithm
    import toppra.constraint

    s = arc_length(points)
    keep = np.concatenate([[True], np.diff(s) > 1e-12])
    s, limit = s[keep], feed_limit(np.asarray(rho, dtype=float)[keep], machine)
    if len(s) < 2:
        return 0.0
    grid = np.union1d(s, np.linspace(0.0, s[-1], steps))
    if straight:
        vertex = np.full(len(grid), machine.feed)
        vertex[np.searchsorted(grid, s)] = limit
        cap = dict(zip(grid.tolist(), vertex.tolist(), strict=True))
    else:
        cap = dict(zip(grid.tolist(), np.interp(grid, s, limit).tolist(), strict=True))

    def speed_limit(x: float) -> np.ndarray:
        v = cap.get(float(x))
        if v is None:  # off the grid: on a G01 segment the feed, on a smooth curve the interpolated limit
            v = machine.feed if straight else float(np.interp(x, s, limit))
        return np.array([[-v, v]])

    toppra.setup_logging("WARNING")
    path = toppra.SplineInterpolator(s, s.reshape(-1, 1))
    constraints = [toppra.constraint.JointVelocityConstraintVarying(speed_limit),
                   toppra.constraint.JointAccelerationConstraint(
                       np.array([[-machine.tangential_acceleration, machine.tangential_acceleration]]))]
    solver = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
    trajectory = solver.compute_trajectory(0.0, 0.0)
    if trajectory is None:
        raise RuntimeError("toppra found no feasible parametrisation (a limit of zero speed?)")
    return float(trajectory.duration)


def stop_at_every_vertex_time(points: np.ndarray, machine: Machine) -> float:
    """Upper bound: rest at every vertex, each segment a rest-to-rest S-curve move capped at the feed."""
    A, J, feed = machine.tangential_acceleration, machine.tangential_jerk, machine.feed
    total = 0.0
    for length in np.diff(arc_length(points)):
        if length <= 0:
            continue
        if 2 * ramp_distance(0.0, feed, A, J) <= length:
            total += 2 * ramp_time(0.0, feed, A, J) + (length - 2 * ramp_distance(0.0, feed, A, J)) / feed
            continue
        lo, hi = 0.0, feed
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if 2 * ramp_distance(0.0, mid, A, J) <= length else (lo, mid)
        total += 2 * ramp_time(0.0, lo, A, J)
    return total
