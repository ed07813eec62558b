"""Seeded sheets of many non-overlapping parts: the inputs of Xie & Zhu's experiments (Table 1).

The paper's sponge sample sets are not published; ours mix the three part families of the
roughness papers (gear, pentagram boss, maple leaf, from :mod:`toolpath.shapes`) with simple
contours (rectangle, circle, ellipse, hexagon), in several sizes and random orientations, placed by
rejection sampling (largest first) at least ``gap`` apart and ``margin`` inside the sheet.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely import affinity
from shapely.geometry import Point, Polygon

from toolpath.shapes.outlines import gear, maple_leaf, pentagram
from toolpath.shapes.sequencing.parts import Part

KINDS = ("gear", "pentagram", "maple_leaf", "rectangle", "circle", "ellipse", "hexagon")


@dataclass(frozen=True)
class Sheet:
    """A rectangular sheet ``[0, width] x [0, height]`` (mm) and the parts laid out on it."""

    width: float
    height: float
    parts: tuple[Part, ...]

    def to_dict(self, decimals: int = 4) -> dict:
        return {"width": self.width, "height": self.height,
                "parts": [{"kind": p.kind, "ring": np.round(p.ring, decimals).tolist()} for p in self.parts]}

    @classmethod
    def from_dict(cls, data: Mapping) -> Sheet:
        try:
            parts = tuple(Part(k, p["kind"], np.asarray(p["ring"], dtype=float)) for k, p in enumerate(data["parts"]))
            return cls(float(data["width"]), float(data["height"]), parts)
        except (KeyError, TypeError) as exc:
            raise ValueError(f"malformed sheet: missing or wrong field {exc}") from None


def outline(kind: str, size: float, rng: np.random.Generator) -> Polygon:
    """One part contour of overall size ``size`` (mm), centred near the origin."""
    if kind == "gear":
        teeth = int(rng.integers(12, 31))
        return gear(module=size / (teeth + 2), teeth=teeth, samples=12)
    if kind == "pentagram":
        return pentagram(size / 2, tip_fillet=0.02 * size, valley_fillet=0.01 * size)
    if kind == "maple_leaf":
        return maple_leaf(size, serrations=int(rng.integers(24, 41)), samples=1440)
    if kind == "rectangle":
        w, h = size, size * rng.uniform(0.35, 0.9)
        return Polygon([(-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2)])
    if kind == "circle":
        return Point(0, 0).buffer(size / 2, quad_segs=16)
    if kind == "ellipse":
        return affinity.scale(Point(0, 0).buffer(size / 2, quad_segs=16), 1.0, rng.uniform(0.4, 0.8))
    if kind == "hexagon":
        a = np.arange(6) * math.pi / 3
        return Polygon(np.column_stack([np.cos(a), np.sin(a)]) * size / 2)
    raise ValueError(f"unknown part kind {kind!r}; choose from {', '.join(KINDS)}")


def make_sheet(n_parts: int, width: float, height: float, kinds: Mapping[str, float],
               size_range: Sequence[float], gap: float, margin: float, simplify: float,
               rng: np.random.Generator, attempts: int = 4000) -> Sheet:
    """``n_parts`` parts drawn by ``kinds`` weights and sizes uniform in ``size_range``, placed apart.

    Raises ValueError naming the part that found no place in ``attempts`` tries (sheet too full).
    """
    names = sorted(kinds)
    weights = np.array([kinds[k] for k in names], dtype=float)
    drawn = rng.choice(len(names), size=n_parts, p=weights / weights.sum())
    sizes = np.sort(rng.uniform(*size_range, size=n_parts))[::-1]
    placed: list[Polygon] = []
    kinds_placed: list[str] = []
    for k, (kind_index, size) in enumerate(zip(drawn, sizes, strict=True)):
        kind = names[kind_index]
        shape = outline(kind, float(size), rng).simplify(simplify, preserve_topology=True)
        for _ in range(attempts):
            turned = affinity.rotate(shape, rng.uniform(0.0, 360.0), origin=(0, 0))
            x0, y0, x1, y1 = turned.bounds
            if x1 - x0 > width - 2 * margin or y1 - y0 > height - 2 * margin:
                raise ValueError(f"part {k} ({kind}, size {size:.1f} mm) does not fit on the sheet")
            dx = rng.uniform(margin - x0, width - margin - x1)
            dy = rng.uniform(margin - y0, height - margin - y1)
            candidate = affinity.translate(turned, dx, dy)
            if not placed or not shapely.dwithin(np.array(placed), candidate, gap).any():
                placed.append(candidate)
                kinds_placed.append(kind)
                break
        else:
            raise ValueError(f"part {k} of {n_parts} ({kind}, size {size:.1f} mm) found no place in "
                             f"{attempts} tries: the sheet {width} x {height} mm is too full")
    parts = tuple(Part(k, kind, np.asarray(p.exterior.coords)) for k, (kind, p)
                  in enumerate(zip(kinds_placed, placed, strict=True)))
    return Sheet(float(width), float(height), parts)
