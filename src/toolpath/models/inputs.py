"""Input preparation shared by every model, and the optional training augmentation.

LocalCurvature (Eq. 3) depends only on the angles between consecutive segments, so it does not
change under translation, rotation, reflection or uniform scaling.  Two inputs are offered, chosen
per model by the ``inputs`` key of ``conf/model/<name>.yaml``:

* ``turning`` (default): per point, ``(1 - cos, sin)`` of the turn between the segments before
  and after it (the terms of Eq. 1-3, signed by the cross product), zero at the two end points and
  where a segment has no length (the rule counts that as no turn).  Roughness is a 0.001-0.03 mm
  ripple on windows tens of millimetres long: in normalised coordinates it is a 1e-4 relative
  signal the networks never found in the default profile's epochs (every learned model predicted
  the majority class), while the turning terms carry it at full scale.
* ``coordinates`` (the paper's input, Sec. 5.1.1): windows moved to their centroid and divided by their
  RMS distance from it (a similarity normalisation: translation and scale, not rotation), floored so
  a degenerate window gives zeros, not NaN; then a learned :class:`DifferenceStem`, the first layers
  of every model on this input.  Fed to the architectures directly, the 1e-4 ripple stayed below
  what they found: every model predicted the majority class.

Both give (B, n, 2), so every architecture after them is unchanged.  No model ever sees the label
or the LocalCurvature value itself.  Random rotation / reflection and traversal reversal are
augmentations for training only (seeded by the caller's generator).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor, nn

_MIN_SCALE = 1e-9
INPUTS = ("turning", "coordinates")


def prepare(windows: Tensor) -> Tensor:
    """Translate each (B, n, 2) window to its centroid and scale it to unit RMS radius."""
    centred = windows - windows.mean(dim=1, keepdim=True)
    rms = centred.pow(2).sum(dim=2).mean(dim=1).sqrt()
    return centred / rms.clamp_min(_MIN_SCALE)[:, None, None]


def turning_terms(windows: Tensor) -> tuple[Tensor, Tensor]:
    """(B, n) each: ``1 - cos theta_i`` and ``sin theta_i`` at each point, Eq. 1-3's terms.

    ``theta_i`` is the turn from segment ``v_{i-1}`` to ``v_i``; the first term summed over a window
    is its LocalCurvature (Eq. 3).  End points and zero-length segments give 0.
    """
    v = windows[:, 1:] - windows[:, :-1]
    length = v.pow(2).sum(dim=2).sqrt()
    denom = length[:, 1:] * length[:, :-1]
    valid = denom > 0
    safe = torch.where(valid, denom, torch.ones_like(denom))
    dot = (v[:, 1:] * v[:, :-1]).sum(dim=2)
    cross = v[:, :-1, 0] * v[:, 1:, 1] - v[:, :-1, 1] * v[:, 1:, 0]
    zero = torch.zeros_like(dot)
    one_minus_cos = torch.where(valid, (1 - dot / safe).clamp(0, 2), zero)
    sin = torch.where(valid, (cross / safe).clamp(-1, 1), zero)
    return F.pad(one_minus_cos, (1, 1)), F.pad(sin, (1, 1))


def turning_features(windows: Tensor) -> Tensor:
    """(B, n, 2): ``(1 - cos theta_i, sin theta_i)`` at each point (:func:`turning_terms`, Eq. 1-3)."""
    return torch.stack(turning_terms(windows), dim=2)


class DifferenceConv(nn.Conv1d):
    """A ``Conv1d`` whose kernel sums to zero over its taps: a learned difference filter.

    The kernel used is the stored weight minus its mean over the taps, so the layer's output does not
    change when the same vector is added to every point (it sees segments, never positions).
    """

    def forward(self, x: Tensor) -> Tensor:
        weight = self.weight - self.weight.mean(dim=2, keepdim=True)
        return F.conv1d(x, weight, self.bias, self.stride, self.padding)


def point_rms_norm(x: Tensor, eps: float = 1e-10) -> Tensor:
    """(B, C, L) with each point's C-vector divided by its RMS over the channels (no learned gain)."""
    return x * torch.rsqrt(x.pow(2).mean(dim=1, keepdim=True) + eps)


class DifferenceStem(nn.Module):
    """The learned first layers of every model on coordinates: (B, 2, n) -> (B, 2, n).

    ``DifferenceConv(2, width, 2)`` (each output a linear function of one segment ``p_{i+1} - p_i``)
    -> :func:`point_rms_norm` (each segment's vector to unit size, so the segment's length drops out
    and only its direction is left, at full scale instead of a 1e-4 ripple) -> ``DifferenceConv(width,
    width, 2)`` (changes of direction between consecutive segments) -> GELU -> ``Conv1d(width, 2, 1)``;
    zero-padded back to n points (the end points have no turn).  Nothing here is a hand-computed
    angle or curvature: every weight is trained with the model.  Measured on gear validation
    (one seed, the CNN, 16 epochs): without the normalisation or without the stem, the majority class.
    """

    def __init__(self, width: int = 16) -> None:
        super().__init__()
        self.segments = DifferenceConv(2, width, 2, bias=False)
        self.turns = DifferenceConv(width, width, 2)
        self.out = nn.Conv1d(width, 2, 1)

    def forward(self, x: Tensor) -> Tensor:
        turns = self.turns(point_rms_norm(self.segments(x)))
        return F.pad(self.out(F.gelu(turns)), (1, 1))


class Prepare(nn.Module):
    """The model's input transform as its first layer, so exported graphs include it.

    ``scale`` (a buffer, saved with the weights) multiplies each input feature; it is 1 until
    :meth:`fit_scale` sets it from the training windows.  A rough window's turning terms are
    0.001-0.07, small enough that a recurrent network's first layer barely moves its state: scaled
    to unit RMS they reach every architecture at the same scale.
    """

    def __init__(self, inputs: str = "turning", stem_width: int = 16) -> None:
        super().__init__()
        if inputs not in INPUTS:
            raise ValueError(f"inputs must be one of {INPUTS}, got {inputs!r}")
        self.inputs = inputs
        self.register_buffer("scale", torch.ones(2))
        # stem_width 0: the coordinates straight to the architecture (the ablation that stays at the
        # majority class); the turning terms need no stem
        self.stem = DifferenceStem(stem_width) if inputs == "coordinates" and stem_width > 0 else None

    def features(self, windows: Tensor) -> Tensor:
        return turning_features(windows) if self.inputs == "turning" else prepare(windows)

    @torch.no_grad()
    def fit_scale(self, windows: Tensor) -> None:
        """Set ``scale`` to the inverse RMS of each feature over ``windows`` (training data only)."""
        rms = self.features(windows).pow(2).mean(dim=(0, 1)).sqrt()
        self.scale.copy_(torch.where(rms > _MIN_SCALE, 1 / rms.clamp_min(_MIN_SCALE), torch.ones_like(rms)))

    def forward(self, windows: Tensor, channels_first: bool = False) -> Tensor:
        """(B, n, 2) scaled features; ``channels_first``: the same values laid out (B, 2, n) for a
        convolution.  A keyword, not a second method, so that an exported graph still attributes the
        ops to this module (``qat.float_modules`` finds them by module)."""
        return self._scaled(windows, dim=1 if channels_first else 2)

    def _scaled(self, windows: Tensor, dim: int) -> Tensor:
        # each feature times its scale before stacking: the same products, but the ONNX graph has two
        # scalar multiplies instead of a Mul broadcasting a 2-vector over (B, n, 2) and no Transpose,
        # operators ONNX Runtime runs a pair of values at a time (0.2 ms each at batch 256, the CNN's
        # whole convolution takes 0.2 ms)
        if self.inputs == "turning":
            turn, sin = turning_terms(windows)
            return torch.stack([turn * self.scale[0], sin * self.scale[1]], dim=dim)
        scaled = prepare(windows) * self.scale
        if self.stem is not None:
            stemmed = self.stem(scaled.transpose(1, 2))
            return stemmed if dim == 1 else stemmed.transpose(1, 2)
        return scaled if dim == 2 else scaled.transpose(1, 2)


def random_rotation_reflection(windows: Tensor, generator: torch.Generator) -> Tensor:
    """Rotate each window by a random angle and reflect half of them (labels are invariant)."""
    batch = windows.shape[0]
    angle = torch.rand(batch, generator=generator) * (2 * math.pi)
    flip = (torch.rand(batch, generator=generator) < 0.5).to(windows.dtype) * 2 - 1
    cos, sin = torch.cos(angle), torch.sin(angle)
    rot = torch.stack([torch.stack([cos, -sin], -1), torch.stack([sin * flip, cos * flip], -1)], -2)
    return torch.einsum("bij,bnj->bni", rot.to(windows.dtype), windows)


def random_reversal(windows: Tensor, generator: torch.Generator) -> Tensor:
    """Traverse half of the windows backwards (labels are invariant: a path's turns are the same
    angles in reverse order, with the opposite sign)."""
    reverse = torch.rand(windows.shape[0], generator=generator) < 0.5
    return torch.where(reverse[:, None, None], windows.flip(1), windows)
