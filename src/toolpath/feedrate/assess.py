"""Plan one path and check the plan (issue 9): machining time, the peak of every constrained quantity
beside its limit, and the two bounds that must bracket the time."""

from __future__ import annotations

import numpy as np

from toolpath.feedrate.bounds import stop_at_every_vertex_time, toppra_time
from toolpath.feedrate.limits import Machine
from toolpath.feedrate.peaks import RELATIVE_SLACK, peaks, within_limits
from toolpath.feedrate.planner import FeedPlan, plan


def assess(points: np.ndarray, rho: np.ndarray, machine: Machine, straight: bool, band: float = np.inf,
           bounds: bool = True) -> tuple[FeedPlan, dict]:
    """The plan and its record: ``time`` (s), ``peaks``, ``within_limits``, and with ``bounds`` the toppra
    ``lower_bound``, the stop-at-every-vertex ``upper_bound`` (G01 paths only: on a densely sampled
    curve it would stop at every sample) and whether they ``bracket`` the planner's time."""
    result = plan(points, rho, machine, straight=straight, band=band)
    found = peaks(result, points, rho, machine)
    record: dict = {"time": result.time, "peaks": found, "within_limits": all(within_limits(found, machine).values())}
    if bounds:
        lower = toppra_time(points, rho, machine, straight=straight)
        upper = stop_at_every_vertex_time(points, machine) if straight else None
        slack = 1 + RELATIVE_SLACK
        record.update(lower_bound=lower, upper_bound=upper,
                      bracketed=bool(lower <= result.time * slack and (upper is None or result.time <= upper * slack)))
    return result, record
