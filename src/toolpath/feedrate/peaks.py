"""The largest chord error, normal acceleration and jerk (Eq. 15, 18, 20) and tangential acceleration
and jerk along a plan, each beside its limit (issue 9).

The normal quantities are evaluated at the path's own samples (where the radius of curvature is
known: on a G01 path its vertices, on a smooth curve its sample points), with the planned speed
there; the tangential ones come from the planned profile itself.
"""

from __future__ import annotations

import numpy as np

from toolpath.feedrate.limits import Machine, chord_error
from toolpath.feedrate.planner import FeedPlan, arc_length

RELATIVE_SLACK = 1e-6  # rounding in the sampled profile


def peaks(result: FeedPlan, points: np.ndarray, rho: np.ndarray, machine: Machine) -> dict[str, float]:
    """Peak of each constrained quantity along the plan."""
    rho = np.asarray(rho, dtype=float)
    v = np.interp(arc_length(points), result.s, result.v)
    curved = np.isfinite(rho) & (rho > 0)
    vc, rc = v[curved], rho[curved]
    if not len(vc):
        vc, rc = np.zeros(1), np.full(1, np.inf)
    return {
        "chord_error": float(np.max(chord_error(vc, rc, machine.period))),
        "normal_acceleration": float(np.max(vc**2 / rc)),
        "normal_jerk": float(np.max(vc**3 / rc**2)),
        "tangential_acceleration": float(np.max(np.abs(result.a))),
        "tangential_jerk": float(np.max(np.abs(result.j))),
        "feed": float(np.max(result.v)),
    }


def limits(machine: Machine) -> dict[str, float]:
    return {"chord_error": machine.chord_error, "normal_acceleration": machine.normal_acceleration,
            "normal_jerk": machine.normal_jerk, "tangential_acceleration": machine.tangential_acceleration,
            "tangential_jerk": machine.tangential_jerk, "feed": machine.feed}


def within_limits(found: dict[str, float], machine: Machine) -> dict[str, bool]:
    """Whether each peak stays at or below its limit."""
    return {k: found[k] <= limit * (1 + RELATIVE_SLACK) for k, limit in limits(machine).items()}
