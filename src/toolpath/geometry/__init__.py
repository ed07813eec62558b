"""Vectorised path geometry (batches of shape (..., n, 2)): Eq. 1-3 and 8-10, deviation; and the 50-point
windows labelled by it (Algorithm 1, Table 1: :mod:`~toolpath.geometry.labels`)."""

from toolpath.geometry.curvature import (
    arc_length,
    drop_repeated,
    fitness,
    local_curvature,
    segment_vectors,
    smoothness_penalty,
    turning_cosines,
)
from toolpath.geometry.deviation import point_to_polyline
from toolpath.geometry.hausdorff import directed_hausdorff, hausdorff

__all__ = [
    "arc_length", "directed_hausdorff", "drop_repeated", "fitness", "hausdorff", "local_curvature",
    "point_to_polyline", "segment_vectors", "smoothness_penalty", "turning_cosines",
]
