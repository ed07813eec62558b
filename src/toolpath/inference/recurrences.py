"""Recurrent layers exported as ONNX recurrences (the opset's ``RNN`` node), or step by step in the fewest nodes.

torch's ONNX exporter writes ``nn.LSTM`` as one ``LSTM`` node but has no translation for the tanh RNN
(``aten.rnn_tanh``): it decomposes it into MatMul / Add / Add / Tanh per time step, with copies of the
weights, so the RNN baseline's file was many times its checkpoint (Table 4d).  :data:`STEPWISE`, the
translation every export here uses (:func:`toolpath.inference.runtimes.export_onnx`), writes the steps
out in the fewest nodes with one copy of each weight; :data:`TRANSLATIONS` maps ``aten.rnn_tanh`` to
the ONNX ``RNN`` operator, and :func:`native_form` gives MCRL's first RNN (a
:class:`~toolpath.models.mcrl.ContextRNN`, whose hoisted recurrence is a Python loop) a form the exporter
sees as one ``nn.RNN`` on the fused input.  Every form is the same function as the network (the benchmark
checks the logits).  Which form runs faster is a property of each runtime's kernels, so the benchmark
times them side by side (Table 4d, beside the shipped lean form of :mod:`toolpath.inference.lean`), and
Table 4d's note says when a run finds the native one faster.
"""

from __future__ import annotations

import copy
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from toolpath.models.mcrl import ContextRNN


def _rnn_tanh(input, hx, params, has_biases: bool, num_layers: int, dropout: float, train: bool,  # noqa: A002
              bidirectional: bool, batch_first: bool):
    """``aten.rnn_tanh.input`` (one forward layer, as every RNN here) as the ONNX ``RNN`` operator:
    ``H_t = tanh(X_t W^T + H_{t-1} R^T + Wb + Rb)``, torch's ``W_ih``, ``W_hh``, ``b_ih``, ``b_hh``."""
    from onnxscript import opset18 as op

    if num_layers != 1 or bidirectional:
        raise NotImplementedError("only one-layer, one-direction tanh RNNs are translated")
    x = op.Transpose(input, perm=[1, 0, 2]) if batch_first else input  # ONNX: (steps, batch, features)
    w, r = op.Unsqueeze(params[0], [0]), op.Unsqueeze(params[1], [0])  # one direction
    b = op.Unsqueeze(op.Concat(params[2], params[3], axis=0), [0]) if has_biases else None
    y, y_last = op.RNN(x, w, r, b, None, hx, activations=["Tanh"], direction="forward",
                       hidden_size=params[1].shape[0])
    y = op.Squeeze(y, [1])  # (steps, directions = 1, batch, hidden) -> (steps, batch, hidden)
    return (op.Transpose(y, perm=[1, 0, 2]) if batch_first else y), y_last


def _rnn_tanh_stepwise(input, hx, params, has_biases: bool, num_layers: int, dropout: float,  # noqa: A002
                       train: bool, bidirectional: bool, batch_first: bool):
    """``aten.rnn_tanh.input`` (one forward layer) written out step by step in the fewest nodes: the input
    projection of every step as one Gemm (both biases in it), then per step one Gemm taking that step's
    projection as its bias input, ``H_t = tanh(H_{t-1} R^T + P_t)``, and one copy of each weight."""
    from onnxscript import opset18 as op

    if num_layers != 1 or bidirectional or not has_biases:
        raise NotImplementedError("only one-layer, one-direction tanh RNNs with biases are written out")
    w_ih, w_hh, b_ih, b_hh = params[:4]
    x = input if batch_first else op.Transpose(input, perm=[1, 0, 2])  # (batch, steps, features)
    steps, hidden = x.shape[1], w_hh.shape[0]  # steps: static, as the windows' length is
    points = op.Reshape(x, op.Constant(value_ints=[-1, w_ih.shape[1]]))
    projected = op.Gemm(points, w_ih, op.Add(b_ih, b_hh), transB=1)
    projected = op.Reshape(projected, op.Constant(value_ints=[-1, steps, hidden]))
    h = op.Squeeze(hx, op.Constant(value_ints=[0]))  # (directions = 1, batch, hidden) -> (batch, hidden)
    outputs = []
    for t in range(steps):
        h = op.Tanh(op.Gemm(h, w_hh, op.Gather(projected, op.Constant(value_int=t), axis=1), transB=1))
        outputs.append(h)
    y = op.Reshape(op.Concat(*outputs, axis=1), op.Constant(value_ints=[-1, steps, hidden]))
    return (y if batch_first else op.Transpose(y, perm=[1, 0, 2])), op.Unsqueeze(h, op.Constant(value_ints=[0]))


TRANSLATIONS: dict[Callable, Callable] = {torch.ops.aten.rnn_tanh.input: _rnn_tanh}
# the default of every export (toolpath.inference.runtimes.export_onnx): tanh RNNs step by step, lean
STEPWISE: dict[Callable, Callable] = {torch.ops.aten.rnn_tanh.input: _rnn_tanh_stepwise}


class FusedInputRNN(nn.RNN):
    """A :class:`ContextRNN` run as the plain ``nn.RNN`` on its fused input (the context repeated at every
    step): the function its docstring states, one recurrence for the exporter instead of a loop."""

    def forward(self, seq: Tensor, context: Tensor) -> Tensor:  # type: ignore[override]
        fused = torch.cat([seq, context[:, None, :].expand(-1, seq.shape[1], -1)], dim=2)
        return nn.RNN.forward(self, fused)[0]


def native_form(net: nn.Module) -> nn.Module:
    """A copy of ``net`` with every :class:`ContextRNN` as a :class:`FusedInputRNN` (same weights)."""
    net = copy.deepcopy(net).eval()
    for module in list(net.modules()):
        for name, child in list(module.named_children()):
            if isinstance(child, ContextRNN):
                fused = FusedInputRNN(child.input_size, child.hidden_size, batch_first=True)
                fused.load_state_dict(child.state_dict())
                setattr(module, name, fused.eval())
    return net


def has_recurrence(net: nn.Module) -> bool:
    return any(isinstance(m, nn.RNN | nn.LSTM) for m in net.modules())


RECURRENT_OPS = ("RNN", "LSTM", "GRU", "Scan", "Loop")


def graph_nodes(path: Path) -> dict:
    """The node count of an ONNX file's graph, how many are recurrences (``RNN`` / ``LSTM`` / ``GRU`` nodes
    and ``Scan`` / ``Loop`` loops) and how many nodes the loops' bodies hold (run once per step)."""
    import onnx

    graph = onnx.load(str(path), load_external_data=False).graph
    ops = Counter(node.op_type for node in graph.node)
    bodies = sum(len(attr.g.node) for node in graph.node for attr in node.attribute if attr.type == attr.GRAPH)
    return {"nodes": sum(ops.values()), "recurrent_nodes": sum(ops[op] for op in RECURRENT_OPS),
            "loop_body_nodes": bodies}


def compare_forms(net: nn.Module, shipped_file: Path, folder: Path, checkpoint: Path, batch: Tensor,
                  time_runners: Callable[[dict], dict], runner: Callable[[Path, str], Callable]) -> dict:
    """The exported FP32 ``net`` in its forms: ``shipped``, the file the benchmark times (``shipped_file``,
    exported already in the lean form, :mod:`toolpath.inference.lean`); ``exporter``, ``net`` as torch's
    exporter unrolls it (the form shipped before the lean one); ``native``, its recurrences as ONNX nodes;
    and, for a network with a :class:`ContextRNN`, ``unhoisted``, that layer unrolled with the input
    projection of the fused input at every step (the form before the hoist); for an MCRL on the turning terms,
    ``compact`` (:mod:`toolpath.inference.compact`: its tanh RNNs as one ``Scan`` loop); all but the first
    exported here into ``folder``.  Per form: bytes and their ratio to the ``checkpoint``, nodes, the largest logit
    difference from the torch network on ``batch``, windows per second in every runtime, all timed by one
    ``time_runners({name: fn})`` call (interleaved, so the ratios are side by side), and
    ``speed_vs_exporter`` per runtime.  ``runner(path, runtime)`` opens a file."""
    from toolpath.inference import compact
    from toolpath.inference.runtimes import RUNTIMES, export_onnx

    plain = native_form(net)
    forms = {"shipped": shipped_file, "exporter": folder / f"{shipped_file.stem}.exporter.onnx",
             "native": folder / f"{shipped_file.stem}.native.onnx"}
    export_onnx(net, batch[:2], forms["exporter"], translations={})
    export_onnx(plain, batch[:2], forms["native"], translations=TRANSLATIONS)
    if any(isinstance(m, ContextRNN) for m in net.modules()):
        forms["unhoisted"] = folder / f"{shipped_file.stem}.unhoisted.onnx"
        export_onnx(plain, batch[:2], forms["unhoisted"], translations={})
    if compact.supported(net):
        forms["compact"] = folder / f"{shipped_file.stem}.compact.onnx"
        compact.save_compact(net, forms["compact"], window=batch.shape[1])
    with torch.inference_mode():
        reference = net.eval()(batch).numpy()
    runners = {f"{form}_{rt}": runner(path, rt) for form, path in forms.items() for rt in RUNTIMES}
    seconds = time_runners({k: (lambda x, run=run: run(x.numpy())) for k, run in runners.items()})
    out: dict = {}
    for form, path in forms.items():
        size = path.stat().st_size
        row = {"file_bytes": size, "bytes_vs_checkpoint": size / checkpoint.stat().st_size, **graph_nodes(path)}
        for rt in RUNTIMES:
            logits = runners[f"{form}_{rt}"](batch.numpy())
            row[f"{rt}_max_logit_diff"] = float(np.abs(logits - reference).max())
            row[f"{rt}_windows_per_s"] = len(batch) / seconds[f"{form}_{rt}"]
            row.setdefault("speed_vs_exporter", {})[rt] = seconds[f"exporter_{rt}"] / seconds[f"{form}_{rt}"]
        out[form] = row
    return out
