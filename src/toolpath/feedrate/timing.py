"""The machining time of a G01 path under the interval planner (:mod:`toolpath.feedrate.planner`),
in NumPy: for whole programs, where the planner's sampled profile and its interval-by-interval
Python loops (a minute for 20,000 points) are more than a time estimate needs.

Same model, same constraints: vertex intervals (choice 1), ramps inside the faster of two
intervals (choice 2), speeds lowered until the ramps fit (choice 3), S-curve ramps
(choice 4).  Two differences in procedure, not in model: the odd intervals whose ramps do not fit are
lowered at once, then the even ones, and these rounds repeat over the intervals next to a change
until every ramp fits (the planner sweeps them one by one), each new speed found by false position
(Illinois) from the slower neighbour's speed, to a relative bracket of 1e-10 (the planner bisects 80
steps from 0); and the time
is summed from the ramp and cruise durations instead of a profile sampled every period.  A test
checks the two agree: to 1e-8 on smooth and lightly rough paths, to 1e-5 where noise larger than
the segments makes the lowering cascade (the two procedures then settle a few ulps apart per step).
"""

from __future__ import annotations

import numpy as np

from toolpath.feedrate.limits import Machine, feed_limit, polyline_radius
from toolpath.feedrate.planner import arc_length

BISECTION_STEPS = 80  # at most, as the planner's
RESOLUTION = 1e-10  # relative: a bisection stops once every bracket is this narrow (a time, not a profile)


def ramp_time(v0: np.ndarray, v1: np.ndarray, acceleration: float, jerk: float) -> np.ndarray:
    """Duration of the S-curve from ``v0`` to ``v1`` (:func:`toolpath.feedrate.scurve.ramp_time`)."""
    dv = np.abs(v1 - v0)
    full = dv >= acceleration * acceleration / jerk
    return np.where(full, acceleration / jerk + dv / acceleration, 2.0 * np.sqrt(np.where(full, 0.0, dv) / jerk))


def ramp_distance(v0: np.ndarray, v1: np.ndarray, acceleration: float, jerk: float) -> np.ndarray:
    return 0.5 * (v0 + v1) * ramp_time(v0, v1, acceleration, jerk)


def vertex_intervals(s: np.ndarray, limit: np.ndarray, feed: float) -> tuple[np.ndarray, ...]:
    """(start, end, speed limit, sensitive) of the intervals of a G01 path (the planner's
    ``_vertex_intervals``): each vertex whose limit lies below the feed is an interval of its own,
    everything between them one non-sensitive interval at the feed."""
    n = len(s)
    vertex = limit < feed
    segment = np.zeros(n, bool)
    segment[:-1] = s[1:] > s[:-1]
    # items in path order: vertex 0, segment 0, vertex 1, ...; segments of zero length dropped
    start = np.stack([s, s], axis=1).ravel()
    end = np.stack([s, np.append(s[1:], s[-1])], axis=1).ravel()
    sensitive = np.stack([vertex, np.zeros(n, bool)], axis=1).ravel()
    speed = np.stack([np.where(vertex, limit, feed), np.full(n, feed)], axis=1).ravel()
    keep = np.stack([np.ones(n, bool), segment], axis=1).ravel()
    start, end, sensitive, speed = start[keep], end[keep], sensitive[keep], speed[keep]
    # consecutive non-sensitive items merge into one interval
    opens = np.ones(len(start), bool)
    opens[1:] = sensitive[1:] | sensitive[:-1]
    first = np.flatnonzero(opens)
    last = np.append(first[1:], len(start)) - 1
    return start[first], end[last], speed[first], sensitive[first]


def _ramps(left: np.ndarray, right: np.ndarray, v: np.ndarray, A: float, J: float) -> np.ndarray:
    """Distance an interval at speed ``v`` needs to ramp from and to its slower neighbours."""
    return (np.where(left < v, ramp_distance(left, v, A, J), 0.0)
            + np.where(right < v, ramp_distance(right, v, A, J), 0.0))


def _excess(left: np.ndarray, right: np.ndarray, space: np.ndarray, A: float, J: float):
    """``excess(v, which)``: the ramps interval ``which`` needs at speed ``v`` beyond its room (increasing
    in ``v``; the new speed is its root)."""
    return lambda v, which: _ramps(left[which], right[which], v, A, J) - space[which]


def _largest_fitting(excess, lo: np.ndarray, hi: np.ndarray, below: np.ndarray, above: np.ndarray):
    """Shrink brackets with ``excess(lo) <= 0 < excess(hi)`` until ``hi - lo <= RESOLUTION hi``, by false
    position with the Illinois rule (an end kept twice has its value halved), which converges in a few
    steps where bisection takes about 35; ``lo`` always fits.  ``excess(v, which)`` evaluates the
    brackets ``which`` at ``v``; only the brackets still open are worked on."""
    lo, hi = lo.copy(), hi.copy()
    which = np.flatnonzero(hi - lo > RESOLUTION * hi)
    a, b, below, above = lo[which], hi[which], below[which], above[which]
    kept = np.zeros(len(which), np.int8)  # -1: lo moved last, +1: hi moved last
    for _ in range(BISECTION_STEPS):
        if not len(which):
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            guess = (a * above - b * below) / (above - below)
        guess = np.where(np.isfinite(guess) & (guess > a) & (guess < b), guess, 0.5 * (a + b))
        value = excess(guess, which)
        fits = value <= 0
        above = np.where(fits & (kept == -1), 0.5 * above, above)  # Illinois: the end that stays is halved
        below = np.where(~fits & (kept == 1), 0.5 * below, below)
        a, below = np.where(fits, guess, a), np.where(fits, value, below)
        b, above = np.where(fits, b, guess), np.where(fits, above, value)
        kept = np.where(fits, -1, 1).astype(np.int8)
        lo[which], hi[which] = a, b
        still = b - a > RESOLUTION * b
        which, a, b, below, above, kept = which[still], a[still], b[still], below[still], above[still], kept[still]
    return lo, hi


def fit_speeds(lengths: np.ndarray, limits: np.ndarray, machine: Machine) -> np.ndarray:
    """Interval speeds <= limits whose ramps to slower neighbours fit inside them (choices 2-3)."""
    A, J = machine.tangential_acceleration, machine.tangential_jerk
    speeds = np.concatenate([[0.0], limits, [0.0]])  # the path starts and ends at rest
    room = np.concatenate([[0.0], lengths, [0.0]])

    n = len(speeds)
    active = np.zeros(n, bool)
    active[1:-1] = True
    while active.any():
        for parity in (0, 1):  # odd and even intervals in turn: a change is seen by its neighbours at once
            candidates = np.flatnonzero(active[parity::2]) * 2 + parity
            active[candidates] = False
            need = _ramps(speeds[candidates - 1], speeds[candidates + 1], speeds[candidates], A, J)
            over = candidates[need > room[candidates] * (1 + 1e-12) + 1e-12]
            if not len(over):
                continue
            left, right, space = speeds[over - 1], speeds[over + 1], room[over]
            excess = _excess(left, right, space, A, J)

            # at the slower neighbour's speed no ramp is needed: the root lies above it (and is it, without room)
            lo = np.minimum(np.minimum(left, right), speeds[over])
            hi = np.where(space > 0, speeds[over], lo)
            lo, hi = _largest_fitting(excess, lo, hi, -space, excess(hi, np.arange(len(over))))
            speeds[over] = lo
            active[over - 1] = active[over + 1] = True
            active[0] = active[-1] = False  # the rest at either end is no interval
    return speeds[1:-1]


def machining_time(points: np.ndarray, machine: Machine, blend_tolerance: float) -> float:
    """Seconds to run the G01 polyline ``points`` (N, 2) from rest to rest, corners blended within
    ``blend_tolerance`` (:func:`toolpath.feedrate.polyline_radius`).

    Raises
    ------
    ValueError
        Where the feed limit is 0 over a stretch of positive length (a cusp), as the planner does.
    """
    points = np.asarray(points, float)
    if len(points) < 2:
        return 0.0
    s = arc_length(points)
    limit = feed_limit(polyline_radius(points, blend_tolerance), machine)
    start, end, speed_limit, _ = vertex_intervals(s, limit, machine.feed)
    lengths = end - start
    v = fit_speeds(lengths, speed_limit, machine)
    A, J = machine.tangential_acceleration, machine.tangential_jerk
    before, after = np.concatenate([[0.0], v[:-1]]), np.concatenate([v[1:], [0.0]])
    up, down = before < v, after < v
    ramp_in = np.where(up, ramp_distance(before, v, A, J), 0.0)
    ramp_out = np.where(down, ramp_distance(v, after, A, J), 0.0)
    cruise = np.maximum(lengths - ramp_in - ramp_out, 0.0)
    stuck = (cruise > 0) & (v <= 0)
    if stuck.any():
        k = int(np.flatnonzero(stuck)[0])
        raise ValueError(f"feed limit 0 over {lengths[k]:.6g} mm from s = {start[k]:.6g} mm: the path has a cusp "
                         "(radius of curvature 0) there and cannot be run")
    seconds = (np.where(up, ramp_time(before, v, A, J), 0.0) + np.where(down, ramp_time(v, after, A, J), 0.0)
               + np.where(cruise > 0, cruise / np.where(v > 0, v, 1.0), 0.0))
    return float(np.sum(seconds))
