"""What a CAM system does to an outline before it becomes G01 code, artefacts included.

1. Offset passes: the finishing pass at the tool radius outside the part, roughing passes further
   out by the finishing stock and a step-over (shapely buffer, round joins as CAM offsets have).
2. Chordal discretisation at a tolerance (Douglas-Peucker on the dense offset, as CAM linearises
   curves), optionally with a maximum segment length (some posts split long blocks).
3. Roughness as real output has it: occasional tiny segments where spans join, optional noise of
   a stated amplitude normal to the path, and coordinates rounded to the output decimals (done by
   the writer), which turns short segments jittery.  Sharp corners are kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import LineString, Polygon


@dataclass(frozen=True)
class Roughness:
    """Artefacts of one program (drawn per program from the ranges in ``conf/generate``).

    chord_tolerance : mm, max sagitta of the chords that replace curves.
    max_segment : mm, longer segments are split evenly (``inf``: never).
    tiny_segment_rate : probability that a segment gets a tiny extra segment at its start.
    tiny_segment_length : mm, length of those tiny segments.
    noise : mm, standard deviation of the normal displacement (0: none).
    noise_span : points per span of the on/off noise envelope; each span is noisy with probability
        ``noise_duty`` (roughness comes and goes along a real path; 0 spans = noise everywhere).
    """

    chord_tolerance: float
    max_segment: float
    tiny_segment_rate: float
    tiny_segment_length: float
    noise: float
    noise_span: int = 0
    noise_duty: float = 1.0


def offset_passes(outline: Polygon, tool_radius: float, finish_stock: float, stepover: float,
                  roughing_passes: int) -> list[np.ndarray]:
    """Closed offset contours, outermost roughing pass first, finishing pass last.

    Each contour is an (n, 2) array that repeats its first point at the end, traversed clockwise
    (climb milling outside the part with a right-hand spindle).
    """
    distances = [tool_radius + finish_stock + stepover * k for k in range(roughing_passes, 0, -1)]
    distances.append(tool_radius)
    passes = []
    for d in distances:
        ring = outline.buffer(d, join_style="round", quad_segs=64)
        if ring.geom_type != "Polygon":
            raise ValueError(f"offset by {d} mm did not give one contour")
        coords = np.asarray(ring.exterior.coords)
        if ring.exterior.is_ccw:
            coords = coords[::-1]
        passes.append(coords)
    return passes


def discretise(contour: np.ndarray, chord_tolerance: float, max_segment: float) -> np.ndarray:
    """Chordal discretisation of a dense contour, then the optional maximum segment length."""
    simplified = np.asarray(LineString(contour).simplify(chord_tolerance, preserve_topology=False).coords)
    if not np.isfinite(max_segment):
        return simplified
    seg = np.diff(simplified, axis=0)
    pieces = np.maximum(1, np.ceil(np.linalg.norm(seg, axis=1) / max_segment).astype(int))
    out = [simplified[:1]]
    for start, end, k in zip(simplified[:-1], simplified[1:], pieces, strict=True):
        t = np.arange(1, k + 1)[:, None] / k
        out.append(start * (1.0 - t) + end * t)  # t = 1 gives `end` exactly: the contour stays closed
    return np.concatenate(out)


def roughen(points: np.ndarray, roughness: Roughness, rng: np.random.Generator) -> np.ndarray:
    """Add tiny segments and normal noise; the first and last point (the closure) stay put."""
    pts = np.asarray(points, dtype=float)
    seg = np.diff(pts, axis=0)
    length = np.linalg.norm(seg, axis=1)
    tiny = (rng.random(len(seg)) < roughness.tiny_segment_rate) & (length > 4 * roughness.tiny_segment_length)
    if tiny.any():
        extra = pts[:-1][tiny] + seg[tiny] / length[tiny, None] * roughness.tiny_segment_length
        idx = np.flatnonzero(tiny) + 1
        pts = np.insert(pts, idx, extra, axis=0)
    if roughness.noise > 0:
        tangent = np.gradient(pts, axis=0)
        norm = np.linalg.norm(tangent, axis=1, keepdims=True)
        normal = np.column_stack([-tangent[:, 1], tangent[:, 0]]) / np.where(norm > 0, norm, 1.0)
        shift = rng.normal(0.0, roughness.noise, len(pts))[:, None] * normal
        if roughness.noise_span > 0:
            spans = rng.random(len(pts) // roughness.noise_span + 1) < roughness.noise_duty
            shift *= np.repeat(spans, roughness.noise_span)[: len(pts), None]
        shift[0] = shift[-1] = 0.0
        pts = pts + shift
    return pts
