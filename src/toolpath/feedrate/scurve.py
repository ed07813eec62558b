"""Jerk-limited (S-curve) speed changes: the ramps of the feedrate planner.

A change from v0 to v1 under tangential acceleration A and jerk J, starting and ending with zero
acceleration, has three phases: jerk +-J for t_j, constant acceleration for t_a, jerk -+J for t_j,
with t_j = A / J and t_a = |dv| / A - A / J when |dv| >= A^2 / J (the acceleration reaches A), and
t_j = sqrt(|dv| / J), t_a = 0 otherwise.  The speed profile is point-symmetric about its middle,
so the distance covered is (v0 + v1) / 2 times the duration.
"""

from __future__ import annotations

import math

import numpy as np


def phase_times(v0: float, v1: float, acceleration: float, jerk: float) -> tuple[float, float]:
    """(t_j, t_a) of the ramp from ``v0`` to ``v1``."""
    dv = abs(v1 - v0)
    if dv >= acceleration * acceleration / jerk:
        return acceleration / jerk, dv / acceleration - acceleration / jerk
    return math.sqrt(dv / jerk), 0.0


def ramp_time(v0: float, v1: float, acceleration: float, jerk: float) -> float:
    t_j, t_a = phase_times(v0, v1, acceleration, jerk)
    return 2.0 * t_j + t_a


def ramp_distance(v0: float, v1: float, acceleration: float, jerk: float) -> float:
    """Distance covered while changing speed from ``v0`` to ``v1``."""
    return 0.5 * (v0 + v1) * ramp_time(v0, v1, acceleration, jerk)


def ramp_samples(v0: float, v1: float, acceleration: float, jerk: float, dt: float
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Time, distance, speed, acceleration and jerk along the ramp, every ``dt`` (end point included)."""
    t_j, t_a = phase_times(v0, v1, acceleration, jerk)
    sign = 1.0 if v1 >= v0 else -1.0
    total = 2.0 * t_j + t_a
    t = np.append(np.arange(0.0, total, dt), total) if total > 0 else np.zeros(1)
    # jerk of each phase, then exact integration phase by phase
    edges = (0.0, t_j, t_j + t_a, total)
    jerks = (sign * jerk, 0.0, -sign * jerk)
    a = np.zeros_like(t)
    v = np.zeros_like(t)
    s = np.zeros_like(t)
    j = np.zeros_like(t)
    a0, vv, ss = 0.0, v0, 0.0
    for k in range(3):
        lo, hi = edges[k], edges[k + 1]
        inside = (t >= lo) & (t <= hi) if k == 2 else (t >= lo) & (t < hi)
        tau = t[inside] - lo
        jj = jerks[k]
        j[inside] = jj
        a[inside] = a0 + jj * tau
        v[inside] = vv + a0 * tau + jj * tau**2 / 2
        s[inside] = ss + vv * tau + a0 * tau**2 / 2 + jj * tau**3 / 6
        d = hi - lo
        ss, vv, a0 = ss + vv * d + a0 * d * d / 2 + jj * d**3 / 6, vv + a0 * d + jj * d * d / 2, a0 + jj * d
    return t, s, v, a, j
