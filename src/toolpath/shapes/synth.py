"""Draw one synthetic CAM program per seed: outline, offset passes, roughness.

Every dimension and artefact comes from a config mapping whose values are either a number (fixed),
``[low, high]`` (uniform; integers when both ends are integers) or ``{log: [low, high]}``
(log-uniform, for tolerances and amplitudes spanning decades).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from shapely import affinity
from shapely.geometry import Polygon

from toolpath.gcode.writer import Pass
from toolpath.shapes import outlines
from toolpath.shapes.cam import Roughness, discretise, offset_passes, roughen


def draw(spec: Any, rng: np.random.Generator) -> float | int:
    """One value from a fixed number, ``[low, high]`` or ``{log: [low, high]}``."""
    if isinstance(spec, Mapping):
        low, high = spec["log"]
        return float(math.exp(rng.uniform(math.log(low), math.log(high))))
    if isinstance(spec, list | tuple):
        low, high = spec
        if isinstance(low, int) and isinstance(high, int):
            return int(rng.integers(low, high + 1))
        return float(rng.uniform(low, high))
    return spec


def draw_all(specs: Mapping[str, Any], rng: np.random.Generator) -> dict[str, float | int]:
    """Draw every key of ``specs`` in sorted order (stable under key reordering in YAML)."""
    return {key: draw(specs[key], rng) for key in sorted(specs)}


def _gear(params: Mapping[str, Any]) -> Polygon:
    return outlines.gear(params["module"], int(params["teeth"]), params["pressure_angle"],
                         params["addendum"], params["dedendum"], params["root_fillet"])


def _pentagram(params: Mapping[str, Any]) -> Polygon:
    return outlines.pentagram(params["outer_radius"], params["inner_ratio"], params["tip_fillet"],
                              params["valley_fillet"])


def _maple_leaf(params: Mapping[str, Any]) -> Polygon:
    return outlines.maple_leaf(params["size"], int(params["serrations"]), params["serration_depth"],
                               params["lobe_depth"], params["lobe_sharpness"])


#: The part families this package can draw, by the name ``conf/generate`` gives their section.  Which
#: of them the pipeline runs is conf/'s ``shapes`` list, not this catalogue.
OUTLINES = {"gear": _gear, "pentagram": _pentagram, "maple_leaf": _maple_leaf}


def outline(shape: str, params: Mapping[str, Any]) -> Polygon:
    """The part outline of ``shape`` for drawn ``params`` (keys as in ``conf/generate``)."""
    if shape not in OUTLINES:
        raise ValueError(f"unknown shape {shape!r}; this package draws {sorted(OUTLINES)}")
    return OUTLINES[shape](params)


def _roughness(rough: dict, rng: np.random.Generator) -> Roughness:
    noisy = rng.random() < rough["noise_probability"]
    return Roughness(chord_tolerance=rough["chord_tolerance"], max_segment=rough["max_segment"],
                     tiny_segment_rate=rough["tiny_segment_rate"], tiny_segment_length=rough["tiny_segment_length"],
                     noise=rough["noise_amplitude"] if noisy else 0.0, noise_span=int(rough["noise_span"]),
                     noise_duty=rough["noise_duty"])


def synthesize(shape: str, shape_spec: Mapping[str, Any], cam_spec: Mapping[str, Any],
               roughness_spec: Mapping[str, Any], rng: np.random.Generator) -> tuple[list[Pass], dict]:
    """Passes of one program and the values drawn for it (recorded in the program header).

    Part and CAM values are drawn once per program, roughness once per pass.
    """
    part = draw_all(shape_spec, rng)
    cam = draw_all(cam_spec, rng)
    part_outline = affinity.rotate(outline(shape, part), cam["rotation"], origin=(0, 0))
    tool_radius = cam["tool_diameter"] / 2.0
    contours = offset_passes(part_outline, tool_radius, cam["finish_stock"],
                             cam["stepover"] * cam["tool_diameter"], int(cam["roughing_passes"]))
    passes, per_pass = [], []
    for contour in contours:  # roughness is drawn per pass: it varies within a program, as in real output
        roughness = _roughness(draw_all(roughness_spec, rng), rng)
        pts = roughen(discretise(contour, roughness.chord_tolerance, roughness.max_segment), roughness, rng)
        passes.append(Pass(pts, z=-abs(cam["depth"])))
        per_pass.append(roughness)
    roughness = per_pass[-1]  # the finishing pass's roughness is recorded alongside the part
    drawn = {**{f"part.{k}": v for k, v in part.items()}, **{f"cam.{k}": v for k, v in cam.items()},
             **{f"roughness.{k}": v for k, v in vars(roughness).items()}}
    return passes, drawn
