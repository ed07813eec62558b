"""A part on the sheet: its closed contour, centroid, envelope rectangle and arc-length positions.

Xie & Zhu call parts "samples".  The centroid is the feature point every sorting rule
uses (Sec. IV); the envelope rectangle is the axis-aligned bounding box.  Positions along a contour
are arc lengths from its first vertex in its own (counter-clockwise) order, so the length of the
contour travelled between an entry and an exit point is ``min(|s1 - s2|, L - |s1 - s2|)`` (Eq. 6).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import shapely
from shapely.geometry import Polygon


@dataclass(frozen=True, eq=False)
class Part:
    """One closed contour: ``ring`` (n, 2) in mm, counter-clockwise, first vertex not repeated."""

    index: int
    kind: str
    ring: np.ndarray

    def __post_init__(self) -> None:
        ring = np.asarray(self.ring, dtype=float)
        if ring.ndim != 2 or ring.shape[1] != 2 or len(ring) < 3:
            raise ValueError(f"part {self.index}: a contour needs at least 3 (x, y) vertices, got {ring.shape}")
        if np.allclose(ring[0], ring[-1]):
            ring = ring[:-1]
        poly = Polygon(ring)
        if not poly.is_valid or poly.area <= 0:
            raise ValueError(f"part {self.index}: the contour is not a simple closed polygon")
        if not poly.exterior.is_ccw:
            ring = ring[::-1].copy()
        object.__setattr__(self, "ring", ring)

    @cached_property
    def polygon(self) -> Polygon:
        poly = Polygon(self.ring)
        shapely.prepare(poly)
        return poly

    @cached_property
    def centroid(self) -> np.ndarray:
        c = self.polygon.centroid
        return np.array([c.x, c.y])

    @cached_property
    def bounds(self) -> np.ndarray:
        """Envelope rectangle ``(xmin, ymin, xmax, ymax)``."""
        return np.array(self.polygon.bounds)

    @cached_property
    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Edge start points and edge vectors of the closed contour, (n, 2) each."""
        return self.ring, np.roll(self.ring, -1, axis=0) - self.ring

    @cached_property
    def positions(self) -> np.ndarray:
        """Arc length from vertex 0 to every vertex, (n,)."""
        lengths = np.hypot(*self.edges[1].T)
        return np.concatenate([[0.0], np.cumsum(lengths)[:-1]])

    @cached_property
    def perimeter(self) -> float:
        return float(np.hypot(*self.edges[1].T).sum())

    def contour_distance(self, s1: np.ndarray | float, s2: np.ndarray | float) -> np.ndarray:
        """Shorter way along the contour between positions ``s1`` and ``s2`` (Eq. 6's min of C and AC)."""
        d = np.abs(np.asarray(s1) - np.asarray(s2)) % self.perimeter
        return np.minimum(d, self.perimeter - d)

    def position_of(self, point: np.ndarray) -> float:
        """Arc-length position of the contour point nearest to ``point``."""
        return float(self.polygon.exterior.project(shapely.Point(point)))

    def point_at(self, s: float) -> np.ndarray:
        p = self.polygon.exterior.interpolate(s % self.perimeter)
        return np.array([p.x, p.y])

    def walk(self, start: float, end: float, forward: bool) -> np.ndarray:
        """Contour points from position ``start`` to ``end`` (inclusive), forward = counter-clockwise.

        ``start == end`` walks the whole loop, as a full cut does.
        """
        total, pos = self.perimeter, self.positions
        start, end = start % total, end % total
        if forward:
            length = (end - start) % total or total
            along = (pos - start) % total
        else:
            length = (start - end) % total or total
            along = (start - pos) % total
        inner = np.argsort(along, kind="stable")
        inner = inner[(along[inner] > 1e-9) & (along[inner] < length - 1e-9)]
        return np.vstack([self.point_at(start), self.ring[inner], self.point_at(end)])
