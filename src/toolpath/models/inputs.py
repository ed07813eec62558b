"""Input preparation shared by every model, and the optional training augmentation.

LocalCurvature (Eq. 3) depends only on the angles between consecutive segments, so it does not
change under translation, rotation, reflection or uniform scaling.  Every model therefore sees
windows moved to their centroid and divided by their RMS distance from it (a Procrustes-style
normalisation): the absolute position on the table and the part size carry no label information
and would only make the networks learn coordinates.  The scale is floored so a degenerate window
(all points equal) gives zeros, not NaN.  Random rotation / reflection is an augmentation for
training only (seeded by the caller's generator); no model ever sees the label or the
LocalCurvature value.
"""

from __future__ import annotations

import math

import torch
from torch import Tensor, nn

_MIN_SCALE = 1e-9


def prepare(windows: Tensor) -> Tensor:
    """Translate each (B, n, 2) window to its centroid and scale it to unit RMS radius."""
    centred = windows - windows.mean(dim=1, keepdim=True)
    rms = centred.pow(2).sum(dim=2).mean(dim=1).sqrt()
    return centred / rms.clamp_min(_MIN_SCALE)[:, None, None]


class Prepare(nn.Module):
    """:func:`prepare` as the first layer of every network, so exported graphs include it."""

    def forward(self, windows: Tensor) -> Tensor:
        return prepare(windows)


def random_rotation_reflection(windows: Tensor, generator: torch.Generator) -> Tensor:
    """Rotate each window by a random angle and reflect half of them (labels are invariant)."""
    batch = windows.shape[0]
    angle = torch.rand(batch, generator=generator) * (2 * math.pi)
    flip = (torch.rand(batch, generator=generator) < 0.5).to(windows.dtype) * 2 - 1
    cos, sin = torch.cos(angle), torch.sin(angle)
    rot = torch.stack([torch.stack([cos, -sin], -1), torch.stack([sin * flip, cos * flip], -1)], -2)
    return torch.einsum("bij,bnj->bni", rot.to(windows.dtype), windows)
