"""Parametric parts (involute gear, pentagram boss, maple leaf) and CAM-like rough G01 toolpaths."""

from toolpath.shapes.cam import Roughness, discretise, offset_passes, roughen
from toolpath.shapes.outlines import gear, maple_leaf, pentagram
from toolpath.shapes.synth import OUTLINES, draw, outline, synthesize

__all__ = [
    "OUTLINES", "Roughness", "discretise", "draw", "gear", "maple_leaf", "offset_passes", "outline",
    "pentagram", "roughen", "synthesize",
]
