"""The NURBS corner paper's three case paths (Figs. 11-14), built parametrically as G01 polylines (mm).

The paper shows them only as pictures, so the sizes are ours; each keeps the character the text
gives it:

* **W** (case 1): the letter W between two horizontal lead lines, five sharp corners.
* **dress** (case 2, "clothes"): a closed, left-right symmetric dress outline mixing large and
  small curvature: sharp shoulder, neck, waist and hem corners joined by arcs (neckline,
  armholes, hem) cut into short chords, as CAM output approximates arcs.
* **torch** (case 3): long straight handle lines at the start and the end (curvature 0, room to
  reach the programmed feed) and, between them, a flame of closely spaced sharp spikes.
"""

from __future__ import annotations

import numpy as np

CASES = ("w", "dress", "torch")


def _arc(center: tuple[float, float], radius: float, start_deg: float, end_deg: float, step_deg: float
         ) -> np.ndarray:
    """Chord points of an arc, both ends included, at most ``step_deg`` apart."""
    count = max(int(np.ceil(abs(end_deg - start_deg) / step_deg)), 1)
    a = np.radians(np.linspace(start_deg, end_deg, count + 1))
    return np.column_stack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a)])


def w_path(width: float = 40.0, height: float = 24.0, lead: float = 10.0) -> np.ndarray:
    """The letter W, its middle peak at 2/3 of the height, with horizontal lead lines."""
    q = width / 4.0
    return np.array([[-lead, height], [0.0, height], [q, 0.0], [2 * q, height * 2 / 3], [3 * q, 0.0],
                     [width, height], [width + lead, height]])


def dress_path(scale: float = 1.0, arc_step_deg: float = 5.0) -> np.ndarray:
    """A closed dress outline, symmetric about x = 0, starting and ending at the middle of the hem."""
    hem_radius = 100.0
    a = np.radians(np.linspace(0.0, np.degrees(np.arcsin(22.0 / hem_radius)), 9))
    hem = np.column_stack([hem_radius * np.sin(a), hem_radius * (1.0 - np.cos(a))])  # a shallow arc
    right = np.vstack([
        hem,
        [[10.0, 30.0]],                                        # waist
        [[13.0, 42.0]],                                        # armpit
        _arc((13.0, 50.0), 8.0, -90.0, -180.0, arc_step_deg)[1:],  # armhole, a concave arc
        [[7.0, 58.0], [4.0, 58.0]],                            # strap top and neck corner
        _arc((0.0, 58.0), 4.0, 0.0, -90.0, arc_step_deg)[1:],  # neckline down to the middle
    ])
    left = right[-2::-1] * [-1.0, 1.0]  # back through the mirror image to the hem middle
    return np.vstack([right, left]) * scale


def torch_path(handle: float = 50.0, spikes: int = 5, spike_height: float = 7.0) -> np.ndarray:
    """Handle up the left, a flared cup, a row of flame spikes, down the right of the handle."""
    cup_half, neck_half = 11.0, 4.0
    x = np.linspace(-cup_half, cup_half, 2 * spikes + 1)
    y = handle + 12.0 + np.where(np.arange(len(x)) % 2 == 1, spike_height, 0.0)
    y[spikes] += spike_height / 2  # the middle spike stands highest
    flame = np.column_stack([x, y])
    return np.vstack([[[-neck_half, 0.0], [-neck_half, handle]], flame, [[neck_half, handle], [neck_half, 0.0]]])


def case_path(name: str) -> np.ndarray:
    """One of :data:`CASES` with its default dimensions."""
    builders = {"w": w_path, "dress": dress_path, "torch": torch_path}
    if name not in builders:
        raise ValueError(f"unknown case {name!r}; known: {', '.join(CASES)}")
    return builders[name]()
