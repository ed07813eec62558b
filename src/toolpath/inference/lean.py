"""Networks in the graph form ONNX Runtime runs fastest, the same function and the same parameters.

torch's exporter writes a linear layer on a (B, L, C) sequence as MatMul + Add, and ONNX Runtime adds the
bias by a broadcast that walks the last axis C elements at a time: most of the time of MCRL's branches
(C = 2 or 16) went to those Adds.  It unrolls a tanh ``nn.RNN`` into per-step MatMul /
Add / Add / Tanh chains and ONNX Runtime's own ``RNN`` kernel is slower still (``make bench``:
``reports/bench/recurrences.json``).  :func:`lean_form` swaps, in a copy of the network, the forward of

* MCRL's branches and their ReLU linear attention: every linear layer on the flattened (B * L, C)
  points, one Gemm with its bias inside;
* MCRL's :class:`~toolpath.models.mcrl.ContextRNN`: the input projection of all steps as one Gemm,
  then per step one Gemm whose bias input is that step's projection, and its Tanh (which ONNX Runtime
  fuses into the Gemm); the first step has no recurrent product (``h_0 = 0``).

A tanh ``nn.RNN`` keeps its fused kernel in torch (QAT trains through it faster than through its steps
written out); its ONNX file gets the same step-wise form from the export translation
:data:`toolpath.inference.recurrences.STEPWISE`.  Module names and parameters stay as they were (the
classes of the modules change, nothing else), so ``qat.float_modules`` names the same layers and a
checkpoint's state dict loads into either form.  Sums are taken in another order, so outputs differ
from the eager network by rounding only (a test bounds it).
"""

from __future__ import annotations

import copy

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from toolpath.models.attention import ReLULinearAttention
from toolpath.models.mcrl import ContextRNN, _Branch


def _pointwise(layer: nn.Linear, x: Tensor) -> Tensor:
    """``layer`` on every point of a (B, L, C) sequence, called as a module on the (B * L, C) points."""
    return layer(x.reshape(-1, x.shape[-1])).reshape(*x.shape[:-1], layer.out_features)


def _recurrence(driven: Tensor, weight_hh: Tensor) -> Tensor:
    """``h_t = tanh(driven_t + W_hh h_{t-1})``, ``h_0 = 0``, over (B, T, H) ``driven``; (B, T, H) out."""
    batch, steps, hidden = driven.shape
    h = torch.tanh(driven[:, 0])
    outputs = [h]
    for t in range(1, steps):
        h = torch.tanh(F.linear(h, weight_hh, driven[:, t]))
        outputs.append(h)
    return torch.cat(outputs, dim=1).reshape(batch, steps, hidden)


class LeanAttention(ReLULinearAttention):
    """:class:`~toolpath.models.attention.ReLULinearAttention` with its projections on the flattened points."""

    def forward(self, x: Tensor) -> Tensor:
        q = _pointwise(self.query, x).relu()
        k = _pointwise(self.key, x).relu()
        v = _pointwise(self.value, x)
        kv = k.transpose(1, 2) @ v
        norm = (q @ k.sum(dim=1, keepdim=True).transpose(1, 2)).clamp_min(self.eps)
        return x + (q @ kv) / norm


class LeanBranch(_Branch):
    """MCRL's branch with its first linear layer on the flattened points (its attention is swapped apart)."""

    def forward(self, x: Tensor) -> Tensor:
        y = _pointwise(self.linear, x)
        if y.shape[1] != self.points:
            y = y.transpose(1, 2)
            y = F.adaptive_avg_pool1d(y, self.points) if self.resample == "area" else \
                F.interpolate(y, size=self.points, mode="linear", align_corners=True)
            y = y.transpose(1, 2)
        return self.attention(y)


class LeanContextRNN(ContextRNN):
    """:class:`~toolpath.models.mcrl.ContextRNN` as :func:`_recurrence` (its hoisted constant as before)."""

    def forward(self, seq: Tensor, context: Tensor) -> Tensor:  # type: ignore[override]
        weight, (batch, steps, width) = self.weight_ih_l0, seq.shape
        constant = F.linear(context, weight[:, self.sequence_size:], self.bias_ih_l0) + self.bias_hh_l0
        driven = F.linear(seq.reshape(batch * steps, width), weight[:, : self.sequence_size])
        return _recurrence(driven.reshape(batch, steps, -1) + constant[:, None, :], self.weight_hh_l0)


_LEAN = {ReLULinearAttention: LeanAttention, _Branch: LeanBranch, ContextRNN: LeanContextRNN}


def lean_form(net: nn.Module) -> nn.Module:
    """A copy of ``net`` in the lean form (see the module docstring); ``net`` itself when it has none of
    the modules it rewrites."""
    if not any(type(module) in _LEAN for module in net.modules()):
        return net
    net = copy.deepcopy(net)
    for module in net.modules():
        if (lean := _LEAN.get(type(module))) is not None:
            module.__class__ = lean
    return net
