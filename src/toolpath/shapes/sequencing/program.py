"""One continuous-cut G-code program for a whole sheet: every move at feed, the tool never lifts.

Each full visit cuts its contour once round from the entry point, in the direction in which the
stretch to the exit is shorter, then carries on to the exit; a via visit follows its contour from
entry to exit the shorter way; transitions are straight G1 moves.  Every visit is announced by a
comment naming the part, its kind and the visit kind, so the program reads like the plan.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from toolpath.gcode.writer import ProgramSpec, fmt, g1_moves
from toolpath.shapes.sequencing.parts import Part
from toolpath.shapes.sequencing.planner import SheetPlan, Visit


def visit_path(part: Part, visit: Visit) -> np.ndarray:
    """The points the tool follows during ``visit``, from its entry to its exit (or back to entry)."""
    total = part.perimeter
    if visit.exit_s is None:
        forward = True
    else:
        ahead = (visit.exit_s - visit.entry_s) % total
        forward = ahead <= total - ahead
    pieces = []
    if visit.full:
        pieces.append(part.walk(visit.entry_s, visit.entry_s, forward))
    if visit.exit_s is not None and part.contour_distance(visit.entry_s, visit.exit_s) > 1e-9:
        pieces.append(part.walk(visit.entry_s, visit.exit_s, forward)[1:] if pieces
                      else part.walk(visit.entry_s, visit.exit_s, forward))
    if not pieces:
        return np.array([part.point_at(visit.entry_s)])
    return np.vstack(pieces)


def sheet_program(plan: SheetPlan, parts: Sequence[Part], spec: ProgramSpec, depth: float, title: str) -> str:
    """The G-code text of ``plan``; ``depth`` is the cutting Z (mm)."""
    d, nl = spec.decimals, spec.newline
    x0, y0 = plan.visits[0].entry_xy
    lines = [f"({title})", "G21 G90 G17 G40 G49 G80", f"S{fmt(spec.spindle, 0)} M3",
             f"G0 Z{fmt(spec.safe_z, d)}", f"G0 X{fmt(x0, d)} Y{fmt(y0, d)}",
             f"G1 Z{fmt(depth, d)} F{fmt(spec.plunge_feed, 0)}"]
    first_feed = True
    for k, visit in enumerate(plan.visits):
        part = parts[visit.part]
        kind = "cut" if visit.full else "follow cut contour (collision avoidance)"
        lines.append(f"(visit {k + 1} of {len(plan.visits)}: part {part.index} {part.kind}, {kind})")
        path = visit_path(part, visit)
        path = np.vstack([visit.entry_xy, path[1:]]) if k else path[1:]  # the plunge already stands at entry 1
        moves = g1_moves(path, d)
        if moves and first_feed:
            moves[0] += f" F{fmt(spec.feed, 0)}"
            first_feed = False
        lines.extend(moves)
    lines += [f"G0 Z{fmt(spec.safe_z, d)}", "M5", "M30"]
    return nl.join(lines) + nl
