"""The parts: parametric outlines (involute gear, pentagram boss, maple leaf) and their CAM-like rough G01
toolpaths (Li et al.), and Xie & Zhu's sheets of many parts with their sequencing
(:mod:`~toolpath.shapes.sequencing`).

The names below load on first use (PEP 562), so an outline alone does not import the G-code writer.
"""

from importlib import import_module

_HOMES = {**{name: "cam" for name in ("Roughness", "discretise", "offset_passes", "roughen")},
          **{name: "outlines" for name in ("gear", "maple_leaf", "pentagram")},
          **{name: "synth" for name in ("OUTLINES", "draw", "outline", "synthesize")}}

__all__ = sorted(_HOMES)


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'toolpath.shapes' has no attribute {name!r}")
    return getattr(import_module(f"toolpath.shapes.{_HOMES[name]}"), name)
