"""Part outlines: involute spur gear, pentagram boss, maple leaf.  Closed shapely polygons (mm).

Outlines are sampled densely (the CAM step in :mod:`toolpath.shapes.cam` discretises them at a
chord tolerance).  Fillets come from morphological opening / closing with a disc, which gives
exact circular fillets tangent to both neighbours: closing (grow, then shrink by rho) rounds the
concave corners only, opening (shrink, then grow) the convex corners only.
"""

from __future__ import annotations

import math

import numpy as np
from shapely.geometry import Polygon

_ROUND = {"join_style": "round", "quad_segs": 64}


def _fillet(poly: Polygon, convex: float = 0.0, concave: float = 0.0) -> Polygon:
    """Round concave corners with radius ``concave`` and convex ones with ``convex``."""
    if concave > 0:
        poly = poly.buffer(concave, **_ROUND).buffer(-concave, **_ROUND)
    if convex > 0:
        poly = poly.buffer(-convex, **_ROUND).buffer(convex, **_ROUND)
    if poly.geom_type != "Polygon":
        raise ValueError("a fillet radius is too large for the outline (it split or vanished)")
    return poly


def _involute(alpha: np.ndarray) -> np.ndarray:
    """inv(a) = tan a - a."""
    return np.tan(alpha) - alpha


def gear(module: float, teeth: int, pressure_angle: float = 20.0, addendum: float = 1.0,
         dedendum: float = 1.25, root_fillet: float = 0.38, samples: int = 40) -> Polygon:
    """Involute spur gear outline (standard, zero backlash), tooth 0 centred on +X.

    Parameters
    ----------
    module : mm.  Pitch radius ``r = module * teeth / 2``.
    pressure_angle : degrees; base radius ``rb = r cos(alpha)``.
    addendum, dedendum : in modules; tip radius ``r + addendum*m``, root ``r - dedendum*m``.
    root_fillet : fillet radius at the root, in modules (0.38 is the ISO 53 basic rack value).
    samples : points per flank and per tip / root land before fillets.

    The flank is the involute of the base circle from ``max(rb, rf)`` to the tip; below the base
    circle (few teeth) it continues radially, as is usual for generated outlines.
    """
    r = module * teeth / 2.0
    alpha = math.radians(pressure_angle)
    rb, ra, rf = r * math.cos(alpha), r + addendum * module, r - dedendum * module
    if rf <= 0:
        raise ValueError("dedendum too large: root radius is not positive")
    half_pitch = math.pi / teeth
    half_thickness = math.pi / (2 * teeth)  # tooth half-thickness angle on the pitch circle

    def flank_angle(radius: np.ndarray) -> np.ndarray:
        rr = np.maximum(radius, rb)
        return half_thickness + _involute(alpha) - _involute(np.arccos(rb / rr))

    radii = np.linspace(rf, ra, samples)
    theta = flank_angle(radii)
    if theta[0] >= half_pitch or theta[-1] <= 0:
        raise ValueError("gear parameters give overlapping or pointed teeth")
    tip = np.linspace(-theta[-1], theta[-1], samples)[1:-1]
    root = np.linspace(theta[0], 2 * half_pitch - theta[0], samples)[1:-1]
    one_tooth = np.concatenate([
        np.column_stack([radii, -theta]),  # right flank, root -> tip
        np.column_stack([np.full_like(tip, ra), tip]),
        np.column_stack([radii[::-1], theta[::-1]]),  # left flank, tip -> root
        np.column_stack([np.full_like(root, rf), root]),
    ])
    pts = []
    for k in range(teeth):
        ang = one_tooth[:, 1] + 2 * half_pitch * k
        pts.append(np.column_stack([one_tooth[:, 0] * np.cos(ang), one_tooth[:, 0] * np.sin(ang)]))
    return _fillet(Polygon(np.concatenate(pts)), concave=root_fillet * module)


def pentagram(outer_radius: float, inner_ratio: float = 0.382, tip_fillet: float = 0.0,
              valley_fillet: float = 0.0, points: int = 5) -> Polygon:
    """Star boss: ``points`` tips at ``outer_radius``, valleys at ``inner_ratio * outer_radius``.

    ``inner_ratio = 0.382`` (1/phi^2) gives the regular pentagram, whose edges are collinear in
    pairs.  Tip and valley fillet radii are in mm (0 keeps the corner sharp).
    """
    angles = math.pi / 2 + np.arange(2 * points) * math.pi / points
    radius = np.where(np.arange(2 * points) % 2 == 0, outer_radius, inner_ratio * outer_radius)
    star = Polygon(np.column_stack([radius * np.cos(angles), radius * np.sin(angles)]))
    return _fillet(star, convex=tip_fillet, concave=valley_fillet)


def _triangle_wave(x: np.ndarray) -> np.ndarray:
    """Period-1 triangle wave in [-1, 1] with sharp extrema (serration teeth)."""
    return 4.0 * np.abs(x - np.floor(x + 0.5)) - 1.0


def maple_leaf(size: float, serrations: int = 40, serration_depth: float = 0.03,
               lobe_depth: float = 0.55, lobe_sharpness: float = 1.5, samples: int = 6000) -> Polygon:
    """Maple-leaf outline as a star-shaped polar curve (so never self-intersecting).

    ``r(t) = size/2 * L(t) * (1 + d * tri(serrations * t / 2pi))`` for polar angle ``t`` from +Y:
    ``L(t) = 1 - lobe_depth * (1 - max_j a_j * max(0, 1 - |t - t_j| / w_j)^lobe_sharpness)``, five
    pointed lobes at 0 (top, a = 1), +-50 deg (a = 0.9) and +-115 deg (a = 0.6), half-width
    ``w_j`` 30 deg; the notch at 180 deg is where a stem would join.  ``tri`` is a triangle wave,
    so every serration has two sharp corners, as the teeth of a real maple leaf do.
    """
    t = np.linspace(-math.pi, math.pi, samples, endpoint=False)
    centres = np.radians([0.0, 50.0, -50.0, 115.0, -115.0])
    amplitude = np.array([1.0, 0.9, 0.9, 0.6, 0.6])
    width = math.radians(30.0)
    dist = np.abs((t[:, None] - centres[None, :] + math.pi) % (2 * math.pi) - math.pi)
    lobes = (amplitude * np.clip(1.0 - dist / width, 0.0, None) ** lobe_sharpness).max(axis=1)
    profile = 1.0 - lobe_depth * (1.0 - lobes)
    r = size / 2.0 * profile * (1.0 + serration_depth * _triangle_wave(serrations * t / (2 * math.pi)))
    return Polygon(np.column_stack([-r * np.sin(t), r * np.cos(t)]))
