"""Networks in the graph form ONNX Runtime runs fastest, the same function and the same parameters.

torch's exporter writes a linear layer on a (B, L, C) sequence as MatMul + Add, and ONNX Runtime adds the
bias by a broadcast that walks the last axis C elements at a time: most of the time of MCRL's branches
(C = 2 or 16) went to those Adds.  It unrolls a tanh ``nn.RNN`` into per-step MatMul /
Add / Add / Tanh chains and ONNX Runtime's own ``RNN`` kernel is slower still (``make bench``:
``reports/bench/recurrences.json``).  :func:`lean_form` swaps, in a copy of the network, the forward of

* the linear layers of MCRL's branches and of their ReLU linear attention: on the flattened
  (B * L, C) points, one Gemm with its bias inside (:class:`PointwiseLinear`, :class:`LeanAttention`);
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


class PointwiseLinear(nn.Linear):
    """``nn.Linear`` on a (B, L, C) sequence as one product over its (B * L, C) points (a Gemm, its bias
    inside); on (B, C) as before."""

    def forward(self, x: Tensor) -> Tensor:
        if x.dim() <= 2:
            return super().forward(x)
        return super().forward(x.reshape(-1, x.shape[-1])).reshape(*x.shape[:-1], self.out_features)


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
    """:class:`~toolpath.models.attention.ReLULinearAttention` with its projections on the flattened points.
    Its projections stay plain ``nn.Linear`` modules, called on (B * L, C): the x86 quantizer annotates a
    linear by its module type, so they stay INT8 as before (a :class:`PointwiseLinear` would be left float)."""

    def forward(self, x: Tensor) -> Tensor:
        def pointwise(layer: nn.Linear) -> Tensor:
            return layer(x.reshape(-1, x.shape[-1])).reshape(*x.shape[:-1], layer.out_features)

        q, k, v = pointwise(self.query).relu(), pointwise(self.key).relu(), pointwise(self.value)
        kv = k.transpose(1, 2) @ v
        norm = (q @ k.sum(dim=1, keepdim=True).transpose(1, 2)).clamp_min(self.eps)
        return x + (q @ kv) / norm


class LeanContextRNN(ContextRNN):
    """:class:`~toolpath.models.mcrl.ContextRNN` as :func:`_recurrence` (its hoisted constant as before)."""

    def forward(self, seq: Tensor, context: Tensor) -> Tensor:  # type: ignore[override]
        weight, (batch, steps, width) = self.weight_ih_l0, seq.shape
        constant = F.linear(context, weight[:, self.sequence_size:], self.bias_ih_l0) + self.bias_hh_l0
        driven = F.linear(seq.reshape(batch * steps, width), weight[:, : self.sequence_size])
        return _recurrence(driven.reshape(batch, steps, -1) + constant[:, None, :], self.weight_hh_l0)


def _lean_class(module: nn.Module, parent: nn.Module | None) -> type | None:
    """The lean class of ``module`` (a child of ``parent``), or None.  MCRL's branch linear is float in QAT
    (``qat.float_modules``), so the x86 quantizer not knowing :class:`PointwiseLinear` changes nothing."""
    if type(module) is ContextRNN:
        return LeanContextRNN
    if type(module) is ReLULinearAttention:
        return LeanAttention
    if type(module) is nn.Linear and type(parent) is _Branch:
        return PointwiseLinear
    return None


def _swaps(net: nn.Module) -> list[tuple[nn.Module, type]]:
    return [(child, lean) for parent in net.modules() for child in parent.children()
            if (lean := _lean_class(child, parent)) is not None]


def lean_form(net: nn.Module) -> nn.Module:
    """A copy of ``net`` in the lean form (see the module docstring); ``net`` itself when it has none of
    the modules it rewrites."""
    if not _swaps(net):
        return net
    net = copy.deepcopy(net)
    for module, lean in _swaps(net):
        module.__class__ = lean
    return net
