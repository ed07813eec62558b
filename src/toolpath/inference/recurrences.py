"""Recurrent layers exported as ONNX recurrences (the opset's ``RNN`` node), beside the unrolled graph.

torch's ONNX exporter writes ``nn.LSTM`` as one ``LSTM`` node but has no translation for the tanh RNN
(``aten.rnn_tanh``): it decomposes it into one MatMul / Add / Tanh chain per time step, 50 steps x 3
layers for the RNN baseline, so its file is many times its checkpoint (Table 4d).  :data:`TRANSLATIONS` maps
``aten.rnn_tanh`` to the ONNX ``RNN`` operator, and :func:`native_form` gives MCRL's first RNN (a
:class:`~toolpath.models.mcrl.ContextRNN`, whose hoisted recurrence is a Python loop) a form the exporter
sees as one ``nn.RNN`` on the fused input.  Both are the same function as the network (the benchmark
checks the logits).  Which form runs faster is a property of each runtime's kernels, so the benchmark
times both side by side (Table 4d); the shipped files keep the unrolled form, and Table 4d's note says
when a run finds the native one faster.
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


TRANSLATIONS: dict[Callable, Callable] = {torch.ops.aten.rnn_tanh.input: _rnn_tanh}


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


def graph_nodes(path: Path) -> dict:
    """The node count of an ONNX file and how many are recurrences (``RNN`` / ``LSTM`` / ``GRU``)."""
    import onnx

    ops = Counter(node.op_type for node in onnx.load(str(path), load_external_data=False).graph.node)
    return {"nodes": sum(ops.values()), "recurrent_nodes": ops["RNN"] + ops["LSTM"] + ops["GRU"]}


def compare_forms(net: nn.Module, shipped_file: Path, folder: Path, checkpoint: Path, batch: Tensor,
                  time_runners: Callable[[dict], dict], runner: Callable[[Path, str], Callable]) -> dict:
    """The exported FP32 ``net`` in its forms: ``unrolled``, the shipped file (``shipped_file``, exported
    already); ``native``, its recurrences as ONNX nodes; and, for a network with a :class:`ContextRNN`,
    ``unhoisted``, that layer unrolled with the input projection of the fused input at every step (the
    form before the hoist), the last two exported here into ``folder``.  Per form: bytes and their ratio
    to the ``checkpoint``, nodes, the largest logit difference from the torch network on ``batch``, windows
    per second in every runtime, all timed by one ``time_runners({name: fn})`` call (interleaved, so the
    ratios are side by side), and ``speed_vs_unrolled`` per runtime.  ``runner(path, runtime)`` opens a file."""
    from toolpath.inference.runtimes import RUNTIMES, export_onnx

    plain = native_form(net)
    forms = {"unrolled": shipped_file, "native": folder / f"{shipped_file.stem}.native.onnx"}
    export_onnx(plain, batch[:2], forms["native"], translations=TRANSLATIONS)
    if any(isinstance(m, ContextRNN) for m in net.modules()):
        forms["unhoisted"] = folder / f"{shipped_file.stem}.unhoisted.onnx"
        export_onnx(plain, batch[:2], forms["unhoisted"])
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
            row.setdefault("speed_vs_unrolled", {})[rt] = seconds[f"unrolled_{rt}"] / seconds[f"{form}_{rt}"]
        out[form] = row
    return out
