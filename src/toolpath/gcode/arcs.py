"""Circular and helical arcs (G2/G3 in the XY plane) discretised within a chord tolerance."""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * math.pi
# The most chords one arc block may become: a full circle of 1 m radius at 0.001 mm is 11,000; past
# a million (24 MB of points) the block is an error, not a request to exhaust memory.
MAX_ARC_POINTS = 1_000_000


# LinuxCNC's interpreter (src/emc/rs274ngc/interp_arc.cc, rs274ngc_interp.hh), in its program's units:
# a centre-format arc is refused when its end radius differs from its start radius by more than 100x the
# absolute spiral tolerance, or by more than it and more than 0.1 % of the larger radius; a radius below
# the radius tolerance is a zero-radius arc; an R arc may fall short of half its chord by that tolerance.
SPIRAL_ABSOLUTE_TOLERANCE = {"mm": 2 * 0.01 * math.sqrt(2), "inch": 2 * 0.001 * math.sqrt(2)}
SPIRAL_RELATIVE_TOLERANCE = 0.001
RADIUS_TOLERANCE = {"mm": 0.00005 * 25.4, "inch": 0.00005}


def centre_arc_problem(r_start: float, r_end: float, units: str) -> str | None:
    """Why LinuxCNC would refuse a centre-format (I/J) arc with these radii (in ``units``, "mm" or
    "inch", the program's), or None when it runs it (as a spiral from one radius to the other)."""
    if min(r_start, r_end) < RADIUS_TOLERANCE[units]:
        return f"zero-radius arc (radius {r_start:.6g} at the start, {r_end:.6g} at the end, {units})"
    absolute = abs(r_start - r_end)
    relative = absolute / max(r_start, r_end)
    limit = SPIRAL_ABSOLUTE_TOLERANCE[units]
    if absolute > 100.0 * limit or (relative > SPIRAL_RELATIVE_TOLERANCE and absolute > limit):
        return (f"radius to the end of the arc differs from the radius to its start by {absolute:.6g} {units} "
                f"(start {r_start:.6g}, end {r_end:.6g}; LinuxCNC allows {limit:.4g} {units}, or "
                f"{SPIRAL_RELATIVE_TOLERANCE:.1%} of the radius up to {100 * limit:.4g} {units})")
    return None


def centre_from_radius(start: np.ndarray, end: np.ndarray, radius: float, clockwise: bool,
                       tolerance: float) -> np.ndarray:
    """Centre of the arc given in R form (RS-274: R < 0 selects the arc longer than 180 degrees).

    Raises
    ------
    ValueError
        When start and end coincide (R cannot define a full circle) or half the chord exceeds the
        radius by more than ``tolerance`` (LinuxCNC's rule; within it the arc is a half circle).
    """
    chord = end[:2] - start[:2]
    d = float(np.hypot(*chord))
    if d == 0.0:
        raise ValueError("an R arc cannot start and end at the same point (use I/J for a full circle)")
    r = abs(radius)
    if d / 2.0 - r > tolerance:
        raise ValueError(f"R arc radius {r:.6g} mm is shorter than half the chord {d / 2:.6g} mm")
    h = math.sqrt(max(r * r - d * d / 4.0, 0.0))
    left = np.array([-chord[1], chord[0]]) / d
    # Minor arc: centre left of the chord for counter-clockwise, right for clockwise.
    side = -1.0 if clockwise else 1.0
    if radius < 0:
        side = -side
    return (start[:2] + end[:2]) / 2.0 + side * h * left


def discretise_arc(start: np.ndarray, end: np.ndarray, centre: np.ndarray, clockwise: bool,
                   chord_tolerance: float, turns: int = 1) -> np.ndarray:
    """Points along an XY arc from ``start`` to ``end`` (exclusive of start, inclusive of end).

    The angular step keeps the sagitta of every chord within ``chord_tolerance``:
    ``step = 2 acos(1 - tol / r)``.  When the end radius differs slightly from the start radius
    (CAM rounding) the radius is blended linearly so the last point is exactly ``end``; Z moves
    linearly with the angle (helix).  ``start == end`` in XY is a full circle.  ``turns`` > 1 adds
    whole revolutions (LinuxCNC's P word).

    Raises
    ------
    ValueError
        When the arc needs more than :data:`MAX_ARC_POINTS` chords.

    Returns
    -------
    ndarray of shape (k, 3)
    """
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
    r0 = math.hypot(start[0] - centre[0], start[1] - centre[1])
    r1 = math.hypot(end[0] - centre[0], end[1] - centre[1])
    sweep = (a0 - a1) % TWO_PI if clockwise else (a1 - a0) % TWO_PI
    if sweep < 1e-12:
        sweep = TWO_PI  # same start and end: a full circle
    sweep += TWO_PI * (max(turns, 1) - 1)
    r_max = max(r0, r1)
    # a circle no larger than the tolerance still gets a few points; 2 acos(1 - x) written as
    # 4 asin(sqrt(x / 2)), which keeps its precision when the radius dwarfs the tolerance
    step = math.pi / 2 if r_max <= chord_tolerance else 4.0 * math.asin(math.sqrt(chord_tolerance / r_max / 2.0))
    count = max(1, math.ceil(sweep / step))
    if count > MAX_ARC_POINTS:
        raise ValueError(f"the arc (radius {r_max:.6g} mm, {sweep / TWO_PI:.6g} turns) needs {count:,} chords "
                         f"within {chord_tolerance:g} mm, more than the limit of {MAX_ARC_POINTS:,}")
    t = np.arange(1, count + 1) / count
    angle = a0 + (-sweep if clockwise else sweep) * t
    radius = r0 + (r1 - r0) * t
    pts = np.empty((count, 3))
    pts[:, 0] = centre[0] + radius * np.cos(angle)
    pts[:, 1] = centre[1] + radius * np.sin(angle)
    pts[:, 2] = start[2] + (end[2] - start[2]) * t
    pts[-1] = end  # exact end point: no drift into the next block
    return pts
