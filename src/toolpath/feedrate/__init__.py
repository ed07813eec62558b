"""Feedrate limits along a path from its curvature (seed 002, Eq. 15-22)."""

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

__all__ = [
    "Machine", "chord_error", "chord_error_limit", "contour_error_limit", "feed_limit",
    "normal_acceleration_limit", "normal_jerk_limit", "polyline_radius",
]
