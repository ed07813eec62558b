"""Algorithm 1 of Li et al.: cut a program's cutting motion into windows and label each by Table 1.

Choices the paper leaves open, made here:

* Only cutting motion is windowed (G1/G2/G3); a rapid breaks the path, and each unbroken run
  starts at the point where the preceding rapid ended.  A window never bridges a rapid.
* Repeated XY points (plunges, zero-length blocks) are dropped before windowing: they have no
  direction, so Eq. 3 is undefined for them.
* The tail of a run shorter than one window is not labelled (it is counted in the summary).
* Windows are stored in float32 relative to their first point (``origin`` keeps that point in
  float64), and the label is computed from exactly the stored float32 values, so anyone can
  recompute every label from the file.
* Table 1 leaves LocalCurvature = 3.5 in no category (Algorithm 1 would send it to 4); it is 3.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from toolpath.gcode.reader import Motion, Program
from toolpath.geometry.curvature import drop_repeated, local_curvature
from toolpath.geometry.labels.categories import TABLE1_BOUNDS, categorize


#: Table 1 bounds: <= 1.9 smooth (1), < 3.5 slightly rough (2), < 7.6 rugged (3), else sharp corner (4).
def feed_runs(program: Program, with_kinds: bool = False) -> list[tuple[np.ndarray, ...]]:
    """Unbroken runs of cutting motion: (xy (k, 2), source line of each point (k,)), and with
    ``with_kinds`` the :class:`Motion` that reaches each point (k,).

    Each run begins with the point the tool stood at before its first cutting move; repeated XY
    points are dropped.
    """
    cutting = program.kinds != Motion.RAPID
    if not cutting.any():
        return []
    edges = np.diff(np.concatenate([[0], cutting.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    runs = []
    for start, stop in zip(starts, stops, strict=True):
        first = max(start - 1, 0)
        xy = program.points[first:stop, :2]
        lines = program.lines_of_points[first:stop]
        xy, keep = drop_repeated(xy)
        runs.append((xy, lines[keep], program.kinds[first:stop][keep]) if with_kinds else (xy, lines[keep]))
    return runs


def arc_share(program: Program, size: int = 50, stride: int = 50) -> np.ndarray:
    """Per window of :func:`label_program` (same order), the share of its points that a G2/G3 arc
    reaches: the reader linearises arcs into chords, so such a window's turns come from the chord
    tolerance, not from CAM roughness."""
    shares = []
    for _, _, kinds in feed_runs(program, with_kinds=True):
        count = 0 if len(kinds) < size else (len(kinds) - size) // stride + 1
        idx = (np.arange(count) * stride)[:, None] + np.arange(size)[None, :]
        shares.append((kinds[idx] == Motion.ARC).mean(axis=1) if count else np.zeros(0))
    return np.concatenate(shares) if shares else np.zeros(0)


@dataclass
class Windows:
    """Labelled windows of one or more programs (arrays aligned on the first axis)."""

    windows: np.ndarray  # (N, size, 2) float32, relative to origin
    origin: np.ndarray  # (N, 2) float64, the first point of each window in the program frame
    local_curvature: np.ndarray  # (N,) float64, Eq. 3 of the stored window
    label: np.ndarray  # (N,) int8, Table 1 category 1-4
    first_line: np.ndarray  # (N,) int32, source line of each window's first point
    unlabelled_points: int = 0  # points in run tails shorter than a window

    def __len__(self) -> int:
        return len(self.label)


def cut_windows(xy: np.ndarray, lines: np.ndarray, size: int = 50, stride: int = 50,
                bounds: tuple[float, float, float] = TABLE1_BOUNDS) -> Windows:
    """Windows of ``size`` points every ``stride`` points along one run (Algorithm 1, step 1)."""
    count = 0 if len(xy) < size else (len(xy) - size) // stride + 1
    starts = np.arange(count) * stride
    idx = starts[:, None] + np.arange(size)[None, :]
    pts = xy[idx] if count else np.zeros((0, size, 2))
    origin = pts[:, 0, :].astype(np.float64) if count else np.zeros((0, 2))
    local = (pts - origin[:, None, :]).astype(np.float32)
    lc = local_curvature(local.astype(np.float64))
    covered = int(starts[-1] + size) if count else 0
    return Windows(local, origin, lc, categorize(lc, tuple(bounds)), lines[starts].astype(np.int32) if count else
                   np.zeros(0, np.int32), unlabelled_points=len(xy) - covered)


def concat(parts: list[Windows], size: int) -> Windows:
    """Stack windows of several runs or programs."""
    if not parts:
        return Windows(np.zeros((0, size, 2), np.float32), np.zeros((0, 2)), np.zeros(0),
                       np.zeros(0, np.int8), np.zeros(0, np.int32))
    return Windows(*(np.concatenate([getattr(p, f) for p in parts]) for f in
                     ("windows", "origin", "local_curvature", "label", "first_line")),
                   unlabelled_points=sum(p.unlabelled_points for p in parts))


def label_program(program: Program, size: int = 50, stride: int = 50,
                  bounds: tuple[float, float, float] = TABLE1_BOUNDS) -> Windows:
    """All labelled windows of one program's cutting motion, categorised by ``bounds`` (Table 1's by
    default; the pipeline passes ``label.bounds``)."""
    return concat([cut_windows(xy, lines, size, stride, bounds) for xy, lines in feed_runs(program)], size)
