"""The benchmark stage's work as functions (Table 4): the FP32 networks exported as ONNX in their INT8
graph's form, side by side before any timing, and each model's files and per-operator profiles."""

from __future__ import annotations

from pathlib import Path

import torch

from toolpath.inference.qat import conv1d_as_conv2d, fp32_twin
from toolpath.inference.recurrences import compare_forms, graph_nodes, has_recurrence
from toolpath.inference.runtimes import RUNTIMES, export_onnx, op_profile, runner
from toolpath.inference.timing import timed
from toolpath.pipeline import artifacts
from toolpath.pipeline.warm_pool import process_pool


def export_fp32(job: tuple) -> int:
    """One FP32 network as ONNX in its INT8 graph's form (in a worker process, on one thread)."""
    checkpoint, producer, float_modules, quantize_conv1d, example, out = job
    torch.set_num_threads(1)
    net = artifacts.load_classifier(checkpoint, producer).network_.eval()
    return export_onnx(fp32_twin(net, float_modules, quantize_conv1d), example, out)


def export_all(jobs: list[tuple], workers: int) -> None:
    """Every export in spawned processes (up to 15 s each for the unrolled recurrent models)."""
    with process_pool(workers) as exporters:
        list(exporters.map(export_fp32, jobs))


def files_and_profiles(fp32_checkpoint: Path, int8_model: Path, fp32_onnx: Path, int8_onnx: Path,
                       qat_metrics: Path, threads: int, batch) -> dict:
    """The sizes of a model's four files (None for an INT8 file the qat stage did not write, with the
    reason) and, where its INT8 ONNX file exists, each runtime's per-operator profile of both ONNX files:
    why INT8 is, or is not, faster."""
    entry = {"fp32_file_bytes": fp32_checkpoint.stat().st_size,
             "int8_file_bytes": int8_model.stat().st_size if int8_model.is_file() else None,
             "fp32_onnx_file_bytes": fp32_onnx.stat().st_size,
             "int8_onnx_file_bytes": int8_onnx.stat().st_size if int8_onnx.is_file() else None,
             "fp32_onnx_nodes": graph_nodes(fp32_onnx)["nodes"],
             "int8_onnx_nodes": graph_nodes(int8_onnx)["nodes"] if int8_onnx.is_file() else None}
    if not int8_model.is_file():
        entry["int8_missing"] = f"{int8_model} not found (see {qat_metrics})"
    if int8_onnx.is_file():
        entry["op_profile"] = {r: {p: op_profile(f, r, threads, batch)
                                   for p, f in (("fp32", fp32_onnx), ("int8", int8_onnx))} for r in RUNTIMES}
    return entry


def draw_inputs(pool: torch.Tensor, batch: int, large: int | None, seed: int) -> dict[str, torch.Tensor]:
    """The timed inputs, seeded draws from ``pool``: one window (``b1``), ``batch`` windows and, where
    ``large`` is set, ``large`` windows (all prefixes of one draw)."""
    draws = torch.Generator().manual_seed(seed)
    pick = torch.randint(0, len(pool), (max(batch, large or 0),), generator=draws)
    inputs = {"b1": pool[pick[:1]], "batch": pool[pick[:batch]]}
    if large:
        inputs["large"] = pool[pick[:large]]
    return inputs


def recurrent_forms(net: torch.nn.Module, checkpoint: Path, fp32_onnx: Path, float_modules, quantize_conv1d: bool,
                    batch: torch.Tensor, bcfg: dict) -> dict | None:
    """A recurrent network's FP32 file in the exporter's own unrolling and with its tanh RNNs as ONNX ``RNN``
    nodes, beside the shipped lean one (:func:`toolpath.inference.recurrences.compare_forms`, timed like
    Table 4); None for a network without recurrences."""
    # the forms beside the shipped file start from the network before its lean form
    twin = conv1d_as_conv2d(net, keep=float_modules).eval() if quantize_conv1d else net.eval()
    if not has_recurrence(twin):
        return None

    def time_runners(runners: dict) -> dict[str, float]:
        seconds = timed(runners, {"batch": batch}, bcfg["repeats"], bcfg["warmup"], warm=batch)
        return {name: s["batch"] for name, s in seconds.items()}

    return compare_forms(twin, fp32_onnx, fp32_onnx.parent, checkpoint, batch, time_runners,
                         lambda path, runtime: runner(path, runtime, bcfg["threads"]))
