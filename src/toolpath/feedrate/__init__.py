"""Feedrate along a path (the NURBS corner paper): limits from curvature (Eq. 15-22), the interval planner with
S-curve ramps, and the two bounds on its machining time."""

from toolpath.feedrate.bounds import stop_at_every_vertex_time, toppra_time
from toolpath.feedrate.limits import (
    Machine,
    chord_error,
    chord_error_limit,
    contour_error_limit,
    feed_limit,
    normal_acceleration_limit,
    normal_jerk_limit,
    polyline_radius,
)
from toolpath.feedrate.planner import FeedPlan, Interval, arc_length, plan

__all__ = [
    "Machine", "chord_error", "chord_error_limit", "contour_error_limit", "feed_limit",
    "normal_acceleration_limit", "normal_jerk_limit", "polyline_radius", "Interval", "FeedPlan", "arc_length", "plan",
    "stop_at_every_vertex_time", "toppra_time",
]
