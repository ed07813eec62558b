"""One tanh RNN layer in ONNX three ways, timed side by side: why Table 4d's native form is not shipped.

Per layer shape (MCRL's first RNN, 20 steps, and the RNN baseline's first layer, 50 steps; batch 256):

* ``native``: the ONNX ``RNN`` operator (:data:`toolpath.inference.recurrences.TRANSLATIONS`), one node;
* ``unrolled``: what torch's exporter writes for ``nn.RNN`` (a MatMul / Add / Tanh chain per step);
* ``lean``: the form the pipeline ships (:data:`toolpath.inference.recurrences.STEPWISE`: the input
  projection of every step as one Gemm, then per step one Gemm whose bias input is that step's
  projection, and a Tanh).

All three are the same function (the largest output difference from ``nn.RNN`` is recorded).  The
timings separate the two costs of Table 4d: a node's fixed overhead (lean against unrolled) and the
runtime's recurrence kernel (native against either).  Issue 45 asks for MCRL as <= 150 nodes, which only
``RNN`` nodes allow (three unrolled layers of 20 steps are at least 120 nodes on their own), and for it
to run 1.5x faster in ONNX Runtime; where ONNX Runtime's ``RNN`` kernel is slower than the unrolled
layer, the two targets pull apart, and this benchmark measures by how much.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from toolpath.inference.recurrences import TRANSLATIONS, graph_nodes
from toolpath.inference.runtimes import RUNTIMES, export_onnx, runner
from toolpath.inference.timing import machine, timed

BATCH = 256


class _Layer(nn.Module):
    """``nn.RNN`` (one layer, batch first) returning only its output sequence."""

    def __init__(self, rnn: nn.RNN) -> None:
        super().__init__()
        self.rnn = rnn

    def forward(self, x: Tensor) -> Tensor:
        return self.rnn(x)[0]


def layer_shapes() -> dict[str, tuple[int, int, int]]:
    """(input width, hidden width, steps) of the recurrent layers the issue names, from the configuration."""
    from toolpath.pipeline import config

    models = config.load().models
    mcrl, rnn = models["mcrl"], models["rnn"]
    # MCRL's first RNN sees its branch's 2 channels fused with the CNN branch's output: its 4 class
    # probabilities (fuse: output) or its hidden vector (fuse: hidden)
    fused = 2 + (4 if mcrl["fuse"] == "output" else mcrl["cnn_hidden"])
    return {"mcrl rnns.0": (fused, mcrl["rnn_hidden"][0], mcrl["points"][2]),
            "rnn layers.0": (2, rnn["hidden"][0], 50)}


def measure_layer(inputs: int, hidden: int, steps: int, threads: int, repeats: int, folder: Path,
                  seed: int = 0) -> dict:
    """The three forms of one seeded ``nn.RNN(inputs, hidden)`` layer on ``steps`` steps, every runtime."""
    generator = torch.Generator().manual_seed(seed)
    torch.manual_seed(seed)
    rnn = nn.RNN(inputs, hidden, batch_first=True).eval()
    x = torch.randn(BATCH, steps, inputs, generator=generator)
    with torch.inference_mode():
        reference = _Layer(rnn)(x).numpy()
    files = {form: folder / f"{form}_{inputs}_{hidden}_{steps}.onnx" for form in ("native", "unrolled", "lean")}
    export_onnx(_Layer(rnn), x[:2], files["native"], translations=TRANSLATIONS)
    export_onnx(_Layer(rnn), x[:2], files["unrolled"], translations={})
    export_onnx(_Layer(rnn), x[:2], files["lean"])  # the default: the step-wise translation
    runs = {f"{form}_{rt}": runner(path, rt, threads) for form, path in files.items() for rt in RUNTIMES}
    seconds = timed({k: (lambda t, run=run: run(t.numpy())) for k, run in runs.items()}, {"batch": x}, repeats)
    out: dict = {"inputs": inputs, "hidden": hidden, "steps": steps, "batch": BATCH}
    for form, path in files.items():
        row = {**graph_nodes(path), "file_bytes": path.stat().st_size}
        for rt in RUNTIMES:
            key = f"{form}_{rt}"
            row[f"{rt}_ms"] = seconds[key]["batch"] * 1e3
            row[f"{rt}_vs_unrolled"] = seconds[f"unrolled_{rt}"]["batch"] / seconds[key]["batch"]
            row[f"{rt}_max_diff"] = float(np.abs(runs[key](x.numpy()) - reference).max())
        out[form] = row
    return out


def measure(threads: int, repeats: int) -> dict:
    """Every layer shape of :func:`layer_shapes`, in scratch files removed afterwards."""
    with tempfile.TemporaryDirectory(prefix="rnn-forms-") as tmp:
        layers = {name: measure_layer(*shape, threads, repeats, Path(tmp))
                  for name, shape in layer_shapes().items()}
    return {"machine": machine(threads), "threads": threads, "repeats": repeats, "layers": layers}
