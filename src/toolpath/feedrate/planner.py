"""Feedrate planning along a path under the NURBS corner paper's constraints (Sec. "Feedrate planning based on
multiple constraints"): sensitive / non-sensitive intervals joined by jerk-limited ramps.

NURBS corner paper (after its ref. 19) splits the path into intervals where the curvature limit v_f of
Eq. 22 lies below the programmed feed (sensitive) and where it does not (non-sensitive), and joins
them with S-curve speed changes under tangential acceleration and jerk limits.  What the text
leaves open, and what we chose:

1. **Intervals.**  As the paper says, a sensitive interval is a run of consecutive sample points
   whose limit lies below the programmed feed, run at its lowest limit (constant speed), so every
   constraint of Eq. 15-22 holds inside it.  Beyond the paper, ``band`` (off in this function; the
   pipeline's ``feedrate.band`` is 0) cuts a run into several intervals whose limits lie within
   ``band`` of each other, so a long curve of varying curvature is not run everywhere at its
   tightest speed; ``band=0`` reads the limit point by point, as a controller's look-ahead does.
   On a G01 path the limits bind at the vertices and the straight segments between them are
   non-sensitive: a single sharp vertex is a sensitive interval of length zero, passed at its limit.
2. **Where ramps go.**  The paper accelerates and decelerates in the non-sensitive intervals; we
   put each speed change wholly inside the faster of its two intervals (deceleration before the
   slower one starts, acceleration after it ends), which is a non-sensitive interval whenever one
   lies between, and otherwise the faster sensitive one, whose speed the ramp never exceeds.  The
   path starts and ends at rest: two virtual intervals of speed 0 and length 0, so a sensitive
   interval at either end hosts its own ramp from or to rest.
3. **Too short to ramp.**  When an interval is too short for the ramps it hosts, its speed is
   lowered (bisection) until they fit; lowering one speed may push a ramp into a neighbour, so the
   pass repeats until no speed changes.  Speeds only fall, so this terminates.
4. **Ramps** are symmetric S-curves (:mod:`toolpath.feedrate.scurve`); the tangential
   acceleration and jerk never exceed their limits, and the acceleration is zero where each ramp
   starts and ends.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolpath.feedrate.limits import Machine, feed_limit
from toolpath.feedrate.scurve import ramp_distance, ramp_samples


@dataclass(frozen=True)
class Interval:
    """A stretch ``[start, end]`` of arc length (mm) run at ``speed`` (mm/s); ``limit`` is its lowest v_f."""

    start: float
    end: float
    limit: float
    sensitive: bool
    speed: float

    @property
    def length(self) -> float:
        return self.end - self.start


@dataclass(frozen=True)
class FeedPlan:
    """A planned path: its intervals, machining time and the profile sampled in time."""

    intervals: tuple[Interval, ...]
    time: float
    t: np.ndarray   # s
    s: np.ndarray   # mm of arc length
    v: np.ndarray   # mm/s
    a: np.ndarray   # tangential acceleration, mm/s^2
    j: np.ndarray   # tangential jerk, mm/s^3


def arc_length(points: np.ndarray) -> np.ndarray:
    """Cumulative arc length at each point of a polyline (mm), starting at 0."""
    seg = np.diff(np.asarray(points, dtype=float), axis=0)
    return np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])


def intervals_from_limits(s: np.ndarray, limit: np.ndarray, feed: float, band: float = np.inf,
                          straight: bool = False) -> list[tuple[float, float, float, bool]]:
    """(start, end, lowest limit, sensitive) of each interval (choice 1 of the module docstring).

    ``straight``: the points are the vertices of a G01 path, joined by straight segments that may
    run at the feed; each vertex whose limit lies below the feed is then an interval of its own.
    """
    if straight:
        return _vertex_intervals(s, limit, feed)
    out: list[tuple[float, float, float, bool]] = []
    k, n = 0, len(s)
    while k < n:
        if limit[k] >= feed:
            m = k
            while m + 1 < n and limit[m + 1] >= feed:
                m += 1
            out.append((s[k], s[m], feed, False))
        else:
            low, high, m = limit[k], limit[k], k
            while m + 1 < n and limit[m + 1] < feed:
                new_low, new_high = min(low, limit[m + 1]), max(high, limit[m + 1])
                if np.isfinite(band) and new_high > new_low * (1.0 + band):
                    break
                low, high, m = new_low, new_high, m + 1
            out.append((s[k], s[m], float(low), True))
        k = m + 1
    return _cover_gaps(out)


def _vertex_intervals(s: np.ndarray, limit: np.ndarray, feed: float) -> list[tuple[float, float, float, bool]]:
    out: list[list] = []
    for k in range(len(s)):
        if limit[k] < feed:
            out.append([s[k], s[k], float(limit[k]), True])
        elif out and not out[-1][3]:
            out[-1][1] = s[k]
        else:
            out.append([s[k], s[k], feed, False])
        if k + 1 < len(s) and s[k + 1] > s[k]:  # the straight segment to the next vertex
            if out[-1][3]:
                out.append([s[k], s[k + 1], feed, False])
            else:
                out[-1][1] = s[k + 1]
    return [tuple(x) for x in out]


def _cover_gaps(items: list[tuple[float, float, float, bool]]) -> list[tuple[float, float, float, bool]]:
    """The segment between the last point of one interval and the first of the next goes to the one
    with the higher limit: on a G01 path the limit binds at the vertex, and the straight segment may
    run faster, so the ramp has room there (on a finely sampled curve this trusts the faster sample
    over one sampling step)."""
    out = [list(x) for x in items]
    for i in range(len(out) - 1):
        gap_start, gap_end = out[i][1], out[i + 1][0]
        if gap_end > gap_start:
            if out[i][2] >= out[i + 1][2]:
                out[i][1] = gap_end
            else:
                out[i + 1][0] = gap_start
    return [tuple(x) for x in out]


def _hosted(speeds: list[float], k: int) -> list[int]:
    """Neighbours of interval k slower than it: k hosts the ramp to each."""
    return [j for j in (k - 1, k + 1) if speeds[j] < speeds[k]]


def fit_speeds(lengths: list[float], limits: list[float], machine: Machine) -> list[float]:
    """Interval speeds <= limits whose ramps fit (choices 2-3); index 0 and -1 are the rest points."""
    A, J = machine.tangential_acceleration, machine.tangential_jerk
    speeds = [0.0, *limits, 0.0]
    lengths = [0.0, *lengths, 0.0]

    def need(k: int, v: float) -> float:
        return sum(ramp_distance(speeds[j], v, A, J) for j in (k - 1, k + 1) if speeds[j] < v)

    changed = True
    while changed:
        changed = False
        for k in range(1, len(speeds) - 1):
            if need(k, speeds[k]) <= lengths[k] * (1 + 1e-12) + 1e-12:
                continue
            lo, hi = 0.0, speeds[k]
            for _ in range(80):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if need(k, mid) <= lengths[k] else (lo, mid)
            speeds[k] = lo
            changed = True
    return speeds[1:-1]


def plan(points: np.ndarray, rho: np.ndarray, machine: Machine, straight: bool = True, band: float = np.inf,
         dt: float | None = None) -> FeedPlan:
    """Plan the feed along ``points`` (N, 2) with radius of curvature ``rho`` (N,) at each point.

    ``straight=True``: a G01 path (the limits bind at its vertices); ``False``: points sampled on a
    smooth curve (NURBS, Bezier); ``band``: see choice 1 of the module docstring.
    """
    s = arc_length(points)
    limit = feed_limit(rho, machine)
    items = intervals_from_limits(s, limit, machine.feed, band, straight)
    speeds = fit_speeds([b - a for a, b, _, _ in items], [lim for _, _, lim, _ in items], machine)
    intervals = tuple(Interval(a, b, lim, sens, v) for (a, b, lim, sens), v in zip(items, speeds, strict=True))
    return _profile(intervals, machine, dt if dt is not None else machine.period)


def _profile(intervals: tuple[Interval, ...], machine: Machine, dt: float) -> FeedPlan:
    """Time, distance, speed, acceleration and jerk through the intervals, and the total time."""
    A, J = machine.tangential_acceleration, machine.tangential_jerk
    speeds = [0.0, *(iv.speed for iv in intervals), 0.0]
    pieces: list[tuple[np.ndarray, ...]] = []
    t0, s0 = 0.0, intervals[0].start if intervals else 0.0
    for k, iv in enumerate(intervals, start=1):
        v = speeds[k]
        before = ramp_distance(speeds[k - 1], v, A, J) if speeds[k - 1] < v else 0.0
        after = ramp_distance(v, speeds[k + 1], A, J) if speeds[k + 1] < v else 0.0
        cruise = max(iv.length - before - after, 0.0)
        if cruise > 0 and v <= 0:
            raise ValueError(f"feed limit 0 over {iv.length:.6g} mm from s = {iv.start:.6g} mm: the path has a "
                             "cusp (radius of curvature 0) there and cannot be run")
        if before:
            t, ds, vv, a, j = ramp_samples(speeds[k - 1], v, A, J, dt)
            pieces.append((t0 + t, s0 + ds, vv, a, j))
            t0, s0 = t0 + t[-1], s0 + ds[-1]
        if cruise > 0 and v > 0:
            steps = max(int(np.ceil(cruise / v / dt)), 1)
            t = np.linspace(0.0, cruise / v, steps + 1)
            pieces.append((t0 + t, s0 + v * t, np.full_like(t, v), np.zeros_like(t), np.zeros_like(t)))
            t0, s0 = t0 + t[-1], s0 + cruise
        if after:
            t, ds, vv, a, j = ramp_samples(v, speeds[k + 1], A, J, dt)
            pieces.append((t0 + t, s0 + ds, vv, a, j))
            t0, s0 = t0 + t[-1], s0 + ds[-1]
    if not pieces:
        zero = np.zeros(1)
        return FeedPlan(intervals, 0.0, zero, zero, zero, zero, zero)
    t, s, v, a, j = (np.concatenate([p[i] for p in pieces]) for i in range(5))
    return FeedPlan(intervals, float(t0), t, s, v, a, j)
