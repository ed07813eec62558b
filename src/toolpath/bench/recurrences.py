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

from toolpath.inference.recurrences import TRANSLATIONS, compare_forms, graph_nodes
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


def measure_mcrl(threads: int, repeats: int, folder: Path, seed: int = 0) -> dict:
    """The configured MCRL (seeded weights, untrained: the timings do not depend on them) in every form of
    Table 4d (:func:`toolpath.inference.recurrences.compare_forms`, the lean form as shipped), on a batch of
    random-walk windows."""
    from toolpath.inference.qat import fp32_twin
    from toolpath.models import registry
    from toolpath.pipeline import config

    generator = torch.Generator().manual_seed(seed)
    torch.manual_seed(seed)
    net = registry.build(config.load().models["mcrl"]).eval()
    windows = (torch.randn(BATCH, 50, 2, generator=generator) * 0.05 + 0.3).cumsum(1)
    net.prepare.fit_scale(windows)
    torch.save(net.state_dict(), folder / "mcrl.pt")
    export_onnx(fp32_twin(net), windows[:2], folder / "mcrl.onnx")

    def time_runners(runs: dict) -> dict[str, float]:
        return {k: s["batch"] for k, s in timed(runs, {"batch": windows}, repeats).items()}

    forms = compare_forms(net, folder / "mcrl.onnx", folder, folder / "mcrl.pt", windows, time_runners,
                          lambda path, runtime: runner(path, runtime, threads))
    return {"batch": BATCH, "forms": forms}


def measure(threads: int, repeats: int) -> dict:
    """Every layer shape of :func:`layer_shapes`, and MCRL whole in every form, in scratch files removed
    afterwards."""
    with tempfile.TemporaryDirectory(prefix="rnn-forms-") as tmp:
        layers = {name: measure_layer(*shape, threads, repeats, Path(tmp))
                  for name, shape in layer_shapes().items()}
        mcrl = measure_mcrl(threads, repeats, Path(tmp))
    return {"machine": machine(threads), "threads": threads, "repeats": repeats, "layers": layers, "mcrl": mcrl}


def print_tables(result: dict) -> None:
    """The measurement as two tables on the terminal: each layer's forms, and MCRL whole."""
    from rich.console import Console
    from rich.table import Table

    threads, repeats = result["threads"], result["repeats"]
    table = Table(title=f"one tanh RNN layer, batch 256, {threads} threads: the ONNX RNN node (native), the exporter's "
                        f"unrolled steps, the fewest-node unrolled form (lean); ms (x speed of unrolled), median of "
                        f"{repeats}")
    for column in ("layer", "form", "nodes", "file kB", "ONNX Runtime", "OpenVINO"):
        table.add_column(column, justify="right")
    for name, layer in result["layers"].items():
        for form in ("native", "unrolled", "lean"):
            row = layer[form]
            table.add_row(f"{name} ({layer['inputs']} -> {layer['hidden']}, {layer['steps']} steps)", form,
                          str(row["nodes"]), f"{row['file_bytes'] / 1e3:,.0f}",
                          *(f"{row[f'{rt}_ms']:.2f} ({row[f'{rt}_vs_unrolled']:.2f}x)" for rt in ("onnxruntime",
                                                                                                  "openvino")))
    Console().print(table)
    whole = Table(title=f"MCRL whole, batch {result['mcrl']['batch']}, {threads} threads: windows/s (x the exporter's "
                        f"unrolling), median of {repeats}")
    for column in ("form", "nodes (+ in loops)", "ONNX Runtime", "OpenVINO"):
        whole.add_column(column, justify="right")
    for form, row in result["mcrl"]["forms"].items():
        whole.add_row(form, f"{row['nodes']} (+{row['loop_body_nodes']})",
                      *(f"{row[f'{rt}_windows_per_s']:,.0f} ({row['speed_vs_exporter'][rt]:.2f}x)"
                        for rt in ("onnxruntime", "openvino")))
    Console().print(whole)
