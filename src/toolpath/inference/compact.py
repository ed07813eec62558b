"""MCRL as a compact ONNX graph written from its weights: its tanh RNNs as one ``Scan`` loop, its branches folded.

torch's exporter writes MCRL in hundreds of nodes (each tanh RNN step by step, each linear layer of a branch as
its own MatMul and Add, each resampling as a dozen gathers); the ``RNN`` operator gives it three nodes, but
ONNX Runtime's ``RNN`` kernel runs several times slower than the same steps written out (``make bench``:
``reports/bench/recurrences.json``).  :func:`compact_mcrl` writes the same function in at most 150 nodes,
its loop's body counted (a test checks it):

* the three tanh RNNs are one ``Scan`` over the batch-first sequence whose body steps every layer (per layer
  a ``Gemm`` with the step's input projection as its bias and a ``Tanh``; above the first, one more ``Gemm``
  projects the new state of the layer below): one loop, no per-step outputs to collect; the first layer's
  projections of all steps are one ``MatMul`` before it, its per-window context projected once
  (:class:`~toolpath.models.mcrl.ContextRNN`);
* the resamplings of all four branches are one ``Gemm`` of the flattened turning terms (average pooling and
  linear interpolation are linear maps along the sequence);
* each branch's ``Linear(2, 2)`` is folded into the query, key and value projections of its attention,
  which become one product; a column of ones beside the values gives the attention's normaliser
  (``phi(q_i) . sum_j phi(k_j)``) from the same product as its numerator;
* the turning terms (Eq. 1-3) are computed as ``(cos - 1, sin)`` per coordinate: the sign and the input
  scale fold into the branches' first products.

The LSTMs stay ONNX ``LSTM`` nodes (ONNX Runtime's kernel is faster than their steps written out).  Sums
are taken in another order, so the logits differ from the torch network by rounding only (a test bounds
it).  Only the turning-terms input is written; :func:`supported` says which networks this form covers.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from toolpath.models.mcrl import MCRL


def supported(net: nn.Module) -> bool:
    """Whether :func:`compact_mcrl` can write ``net``: an MCRL on the turning terms."""
    return isinstance(net, MCRL) and net.prepare.inputs == "turning"


def _array(t: torch.Tensor) -> np.ndarray:
    return t.detach().to(torch.float64).numpy()


class _Graph:
    """Nodes and initialisers under construction, with fresh names."""

    def __init__(self) -> None:
        self.nodes: list = []
        self.initializers: list = []
        self._count = 0

    def const(self, value, dtype=np.float32) -> str:
        from onnx import numpy_helper

        name = f"c{len(self.initializers)}"
        self.initializers.append(numpy_helper.from_array(np.asarray(value, dtype=dtype), name))
        return name

    def op(self, op_type: str, *inputs: str, outputs: int = 1, name: str | None = None, **attrs) -> str | list[str]:
        from onnx import helper

        names = [name] if name else [f"{op_type.lower()}{self._count}_{i}" for i in range(outputs)]
        self._count += 1
        self.nodes.append(helper.make_node(op_type, list(inputs), names, name=names[0], **attrs))
        return names[0] if outputs == 1 else names


def _slice(g: _Graph, x: str, start: int, end: int, axis: int, step: int = 1) -> str:
    return g.op("Slice", x, g.const([start], np.int64), g.const([end], np.int64), g.const([axis], np.int64),
                g.const([step], np.int64))


_END = 2**62  # a Slice's "to the end"


def _turning(g: _Graph, windows: str) -> tuple[str, np.ndarray]:
    """(B, 2 (n - 2)) ``(cos - 1, sin)`` of each inner point's turn (Eq. 1-3), channel by channel, zero where
    a segment has no length (the end points have no turn: zero, left out); and the per-channel factor that
    makes them the network's scaled ``(1 - cos, sin)`` terms.
    Computed per coordinate on (B, n) tensors: ONNX Runtime broadcasts slowly over a last axis of 1 or 2,
    and its transpose optimiser moves a channels-first layout back to channels last."""
    flat = g.op("Reshape", windows, g.const([0, -1], np.int64))  # (B, 2n): x0, y0, x1, y1, ...
    v = g.op("Sub", _slice(g, flat, 2, _END, 1), _slice(g, flat, 0, -2, 1))
    vx, vy = _slice(g, v, 0, _END, 1, step=2), _slice(g, v, 1, _END, 1, step=2)  # (B, n - 1) segments
    ax, bx, ay, by = (_slice(g, c, *ends, 1) for c in (vx, vy) for ends in ((0, -1), (1, _END)))
    dot = g.op("Add", g.op("Mul", ax, bx), g.op("Mul", ay, by))
    cross = g.op("Sub", g.op("Mul", ax, by), g.op("Mul", ay, bx))
    length = g.op("Sqrt", g.op("Add", g.op("Mul", vx, vx), g.op("Mul", vy, vy)))
    denom = g.op("Mul", _slice(g, length, 0, -1, 1), _slice(g, length, 1, _END, 1))  # (B, n - 2)
    valid = g.op("Greater", denom, g.const(0.0))
    safe = g.op("Where", valid, denom, g.const(1.0))
    zero, one = g.const(0.0), g.const(1.0)
    cos = g.op("Clip", g.op("Div", dot, safe), g.const(-1.0), one)
    sin = g.op("Clip", g.op("Div", cross, safe), g.const(-1.0), one)
    channels = [g.op("Where", valid, c, zero) for c in (g.op("Sub", cos, one), sin)]
    return g.op("Concat", *channels, axis=1), np.array([-1.0, 1.0])


def _resampling(points: int, window: int, resample: str) -> np.ndarray:
    """The (points x window) matrix of a branch's resampling along the sequence (a linear map; the identity
    where the branch keeps the window's points)."""
    if points == window:
        return np.eye(window)
    basis = torch.eye(window, dtype=torch.float64)[None]  # (1, window channels, window points)
    out = F.adaptive_avg_pool1d(basis, points) if resample == "area" else \
        F.interpolate(basis, size=points, mode="linear", align_corners=True)
    return out[0].T.numpy()


def _resampled(g: _Graph, net: MCRL, terms: str, window: int) -> list[str]:
    """Each branch's input as (B * p, 2) points: the window's terms, or their resampling to p points.  One
    Gemm maps the (B, 2 (n - 2)) inner terms to every branch's points in point-major order (the zero end
    points drop out; a Gemm beats a product broadcast over the batch)."""
    inner = np.eye(window)[:, 1:-1]  # (window, window - 2): the points that have a turn
    maps = [np.kron(_resampling(b.points, window, b.resample) @ inner, np.eye(2)) for b in net.branches]
    # kron rows are point-major (p0 channel 0, p0 channel 1, ...); the terms are channel-major
    rows = np.arange(2 * (window - 2)).reshape(window - 2, 2).T.ravel()
    product = g.op("Gemm", terms, g.const(np.concatenate(maps, axis=0)[:, rows].T))
    pieces = g.op("Split", product, g.const([2 * b.points for b in net.branches], np.int64), axis=1,
                  outputs=len(maps))
    return [g.op("Reshape", piece, g.const([-1, 2], np.int64)) for piece in pieces]


def _branch(g: _Graph, net: MCRL, k: int, points: str, factor: np.ndarray) -> str:
    """Branch ``k`` on its (B * p, 2) points: ``Linear(2, 2)`` and ReLU linear attention with its
    residual, (B, p, 2)."""
    branch = net.branches[k]
    att = branch.attention
    lin_w, lin_b = _array(branch.linear.weight) * factor[None, :], _array(branch.linear.bias)
    blocks_w, blocks_b = [lin_w], [lin_b]  # y = x W^T + b, then q, k, v of y, then a constant 1
    for layer in (att.query, att.key, att.value):
        w, b = _array(layer.weight), _array(layer.bias)
        blocks_w.append(w @ lin_w)
        blocks_b.append(w @ lin_b + b)
    blocks_w.append(np.zeros((1, 2)))
    blocks_b.append(np.ones(1))
    width, channels = att.query.out_features, att.value.out_features
    # one Gemm over the (B * p, 2) points, its bias inside: a broadcast Add on (B, p, C) is slow in ONNX Runtime
    z = g.op("Gemm", points, g.const(np.concatenate(blocks_w)),
             g.const(np.concatenate(blocks_b)), transB=1)
    z = g.op("Reshape", z, g.const([-1, branch.points, len(np.concatenate(blocks_b))], np.int64))
    y, qk, values = g.op("Split", z, g.const([2, 2 * width, channels + 1], np.int64), axis=2, outputs=3)
    q, keys = g.op("Split", g.op("Relu", qk), g.const([width, width], np.int64), axis=2, outputs=2)
    attended = g.op("MatMul", q, g.op("MatMul", g.op("Transpose", keys, perm=[0, 2, 1]), values))
    numerator, norm = g.op("Split", attended, g.const([channels, 1], np.int64), axis=2, outputs=2)
    return g.op("Add", y, g.op("Div", numerator, g.op("Clip", norm, g.const(float(att.eps)))))


def _conv1d(conv: nn.Module) -> tuple[np.ndarray, np.ndarray, int]:
    """Weight (out, in, k), bias and padding of MCRL's convolution, a ``Conv1d`` or its 2-D twin
    (:class:`toolpath.inference.qat.Conv1dAs2d`, which keeps the 1-D weights as height-1 kernels)."""
    inner = getattr(conv, "conv", conv)
    weight = _array(inner.weight)
    padding = inner.padding[-1]
    if weight.ndim == 4:
        weight = weight[:, :, 0, :]
    if inner.stride[-1] != 1 or inner.dilation[-1] != 1 or inner.groups != 1 or not isinstance(padding, int):
        raise ValueError(f"the compact form writes MCRL's plain convolution, not {inner}")
    return weight, _array(inner.bias), padding


def _linear(g: _Graph, x: str, layer: nn.Linear) -> str:
    return g.op("Gemm", x, g.const(_array(layer.weight)), g.const(_array(layer.bias)), transB=1)


def _context(g: _Graph, net: MCRL, k: int, hidden: str) -> tuple[str, str]:
    """What branch k + 1 is fused with, and branch k's logits."""
    logits = _linear(g, hidden, net.heads[k])
    return (hidden if net.fuse == "hidden" else g.op("Softmax", logits, axis=1)), logits


def _fused(g: _Graph, seq: str, context: str, steps: int) -> str:
    """(B, L, D) sequence with a (B, C) context at every step -> (B, L, D + C)."""
    repeated = g.op("Expand", g.op("Unsqueeze", context, g.const([1], np.int64)), g.const([1, steps, 1], np.int64))
    return g.op("Concat", seq, repeated, axis=2)


def _rnn_stack(g: _Graph, projected: str, layers: list[nn.RNN], zeros: dict[int, str]) -> str:
    """Stacked tanh RNNs as one ``Scan`` that steps every layer at each time step; the first layer's input
    projections (both biases in them) are its scan input: layer ``l`` computes
    ``h_l = tanh(h_{l-1} W_l^T + b_l + h_l R_l^T)`` from the layer below's new state, the same sums as
    layer after layer.  Returns the last layer's last state (B, H)."""
    from onnx import TensorProto, helper

    nodes, states = [], [f"h{i}" for i in range(len(layers))]
    below = None
    for i, layer in enumerate(layers):
        recurrent = g.const(_array(layer.weight_hh_l0))
        if i == 0:
            bias = "p"
        else:  # this step's input projection of the layer below's new state, both biases in it
            bias = f"x{i}"
            nodes.append(helper.make_node("Gemm", [below, g.const(_array(layer.weight_ih_l0)),
                                                   g.const(_array(layer.bias_ih_l0) + _array(layer.bias_hh_l0))],
                                          [bias], transB=1))
        nodes += [helper.make_node("Gemm", [states[i], recurrent, bias], [f"g{i}"], transB=1),
                  helper.make_node("Tanh", [f"g{i}"], [f"{states[i]}_next"])]
        below = f"{states[i]}_next"

    def info(name: str, width: int):
        return helper.make_tensor_value_info(name, TensorProto.FLOAT, ["batch", width])

    widths = [layer.hidden_size for layer in layers]
    body = helper.make_graph(nodes, f"steps{g._count}",
                             [info(h, w) for h, w in zip(states, widths, strict=True)] + [info("p", widths[0])],
                             [info(f"{h}_next", w) for h, w in zip(states, widths, strict=True)])
    finals = g.op("Scan", *(zeros[w] for w in widths), projected, outputs=len(layers), body=body,
                  num_scan_inputs=1, scan_input_axes=[1])
    return finals[-1] if len(layers) > 1 else finals


def _lstm(g: _Graph, x: str, layer: nn.LSTM) -> tuple[str, str]:
    """One ``nn.LSTM`` layer on a (T, B, I) input as an ONNX ``LSTM``: its (T, B, H) outputs and (B, H) last."""
    hidden = layer.hidden_size
    order = np.r_[0:hidden, 3 * hidden:4 * hidden, hidden:2 * hidden, 2 * hidden:3 * hidden]  # torch ifgo -> iofc
    w, r = _array(layer.weight_ih_l0)[order][None], _array(layer.weight_hh_l0)[order][None]
    b = np.concatenate([_array(layer.bias_ih_l0)[order], _array(layer.bias_hh_l0)[order]])[None]
    y, y_last = g.op("LSTM", x, g.const(w), g.const(r), g.const(b), hidden_size=hidden, outputs=2)
    return g.op("Squeeze", y, g.const([1], np.int64)), g.op("Squeeze", y_last, g.const([0], np.int64))


def compact_mcrl(net: MCRL, window: int = 50):
    """``net`` (an MCRL on the turning terms, eval mode) as an ONNX model: input ``windows`` (B, window, 2),
    output ``logits`` (B, classes)."""
    from onnx import TensorProto, helper

    if not supported(net):
        raise ValueError("the compact form is written for MCRL on the turning terms only")
    g = _Graph()
    terms, sign = _turning(g, "windows")
    factor = sign * _array(net.prepare.scale)
    b1, b2, b3, b4 = (_branch(g, net, k, points, factor) for k, points in enumerate(_resampled(g, net, terms, window)))
    h = g.op("Reshape", b1, g.const([0, -1], np.int64))
    for layer in net.mlp:
        h = _linear(g, h, layer) if isinstance(layer, nn.Linear) else g.op("Relu", h)
    context, logits0 = _context(g, net, 0, h)
    steps = net.branches[1].points
    weight, bias, pad = _conv1d(net.conv)
    c = g.op("Conv", g.op("Transpose", _fused(g, b2, context, steps), perm=[0, 2, 1]), g.const(weight), g.const(bias),
             pads=[pad, pad], kernel_shape=[weight.shape[2]])
    c = g.op("MaxPool", g.op("Relu", c), kernel_shape=[net.pool.kernel_size], strides=[net.pool.stride])
    h = g.op("Relu", _linear(g, g.op("Reshape", c, g.const([0, -1], np.int64)), net.cnn_fc))
    context, logits1 = _context(g, net, 1, h)
    first, *rest = net.rnns
    seq_w = _array(first.weight_ih_l0)
    constant = g.op("Gemm", context, g.const(seq_w[:, first.sequence_size:]),
                    g.const(_array(first.bias_ih_l0) + _array(first.bias_hh_l0)), transB=1)
    projected = g.op("Add", g.op("MatMul", b3, g.const(seq_w[:, :first.sequence_size].T)),
                     g.op("Unsqueeze", constant, g.const([1], np.int64)))
    zeros = {}  # h_0 = 0 per width: a product of the context by a zero matrix gives (B, H) zeros
    for width in {layer.hidden_size for layer in net.rnns}:
        zeros[width] = g.op("MatMul", context, g.const(np.zeros((first.input_size - first.sequence_size, width))))
    r = _rnn_stack(g, projected, list(net.rnns), zeros)
    context, logits2 = _context(g, net, 2, r)
    s = g.op("Transpose", _fused(g, b4, context, net.branches[3].points), perm=[1, 0, 2])
    for layer in net.lstms:
        s, last = _lstm(g, s, layer)
    logits3 = _linear(g, last, net.heads[3])
    g.op("Gemm", g.op("Concat", logits0, logits1, logits2, logits3, axis=1), g.const(_array(net.fusion.weight)),
               g.const(_array(net.fusion.bias)), transB=1, name="logits")
    graph = helper.make_graph(g.nodes, "mcrl_compact",
                              [helper.make_tensor_value_info("windows", TensorProto.FLOAT, ["batch", window, 2])],
                              [helper.make_tensor_value_info("logits", TensorProto.FLOAT, ["batch", None])],
                              g.initializers)
    return helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)], producer_name="toolpath")


def save_compact(net: MCRL, path: Path, window: int = 50) -> int:
    """:func:`compact_mcrl` written to ``path``; returns its size in bytes."""
    import onnx

    path.parent.mkdir(parents=True, exist_ok=True)
    onnx.save(compact_mcrl(net.eval(), window), str(path))
    return path.stat().st_size
