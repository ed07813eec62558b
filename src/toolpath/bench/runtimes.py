"""Which runtime runs our INT8 models fastest here: the measurement behind Table 4's INT8 artefact.

For each model, its trained FP32 network and its QAT INT8 graph (``models/int8/<model>/<shape>.pt2``,
the learned scales included) are run side by side in one process by

* torch: FP32 eager, and the INT8 graph eager (the reference graph: dequantize -> float op -> quantize);
* ONNX Runtime: both exported to ONNX (``torch.onnx.export(..., dynamo=True)``; the INT8 graph becomes
  a QDQ model, which ONNX Runtime fuses into QLinear kernels where it can);
* OpenVINO: the same two ONNX files, compiled for the CPU with f32 as the inference precision (its
  default on this CPU, bf16, changes FP32 predictions), its INT8 kernels taking the QDQ pairs.

The same ONNX file runs in both runtimes, so the weights and scales timed are the ones QAT learned.

Beside them, one row that is not QAT: ``onnxruntime_ptq``, ONNX Runtime's own static quantisation of
the FP32 file (:func:`static_int8`: calibrated on training windows, every Conv / MatMul / Gemm but the
first quantised *with its output*, so that ONNX Runtime fuses each into one QLinear kernel).  The QAT
graph quantises a convolution's output only where the next op is quantised too, so in ONNX Runtime
most of its convolutions stay float; this row measures what the fused form would gain.
Protocol as the benchmark stage's (:func:`toolpath.inference.timing.timed`): fixed threads, warm-up,
repetitions interleaved over every variant, medians; batch 1 and ``batch``.  Each variant's test-split
accuracy is measured too, so a speed-up never hides an accuracy loss.  Timings vary from run to run.
Where INT8 is not faster, ``onnxruntime_int8_op_profile`` shows why: ONNX Runtime's own per-operator
profile of the INT8 graph, split into integer kernels, float <-> int8 conversions and float operators.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import torch

from toolpath.inference.runtimes import export_onnx, load_int8_program, onnxruntime_runner, op_profile, openvino_runner

RUNTIMES = ("torch", "onnxruntime", "openvino")


QUANTIZED_OPS = ("Conv", "MatMul", "Gemm")


def static_int8(fp32_onnx: Path, calibration: np.ndarray, out: Path, batch: int = 64) -> int:
    """ONNX Runtime's static QDQ quantisation of an FP32 ONNX file (per-channel INT8 weights, 7-bit
    activations as the qat stage's ``reduce_range``), min-max calibrated on ``calibration`` windows:
    every Conv / MatMul / Gemm but the first (it sees the raw turning terms, as ``qat.float_modules``
    keeps such layers float) with its inputs and its output.  Returns the file size in bytes."""
    import logging

    import onnx
    from onnxruntime.quantization import CalibrationDataReader, QuantFormat, QuantType, quantize_static
    from onnxruntime.quantization.shape_inference import quant_pre_process

    class Windows(CalibrationDataReader):
        def __init__(self) -> None:
            x = np.ascontiguousarray(calibration, dtype=np.float32)
            self.batches = iter([{"windows": x[i:i + batch]} for i in range(0, len(x), batch)])

        def get_next(self) -> dict | None:
            return next(self.batches, None)

    root, level = logging.getLogger(), logging.getLogger().level
    root.setLevel(max(level, logging.WARNING))  # its per-node notes go to the root logger
    prepared = out.with_suffix(".pre.onnx")
    try:
        quant_pre_process(str(fp32_onnx), str(prepared))
        first = next(n.name for n in onnx.load(str(prepared)).graph.node if n.op_type in QUANTIZED_OPS)
        quantize_static(str(prepared), str(out), Windows(), quant_format=QuantFormat.QDQ, per_channel=True,
                        reduce_range=True, activation_type=QuantType.QUInt8, weight_type=QuantType.QInt8,
                        op_types_to_quantize=list(QUANTIZED_OPS), nodes_to_exclude=[first])
    finally:
        root.setLevel(level)
        prepared.unlink(missing_ok=True)
    return out.stat().st_size


def runners(fp32: torch.nn.Module, int8_file: Path | None, example: torch.Tensor, threads: int,
            workdir: Path, calibration: np.ndarray | None = None,
            onnx_fp32: torch.nn.Module | None = None) -> tuple[dict, dict]:
    """Every (runtime, precision) variant of one model as ``{"<runtime>_<fp32|int8>": callable}``, and the
    ONNX file sizes; with ``calibration`` windows also ``onnxruntime_ptq`` (:func:`static_int8`).  A
    runtime that cannot load a file is left out with its reason under ``errors``.  ``onnx_fp32``: the
    network exported for the ONNX runtimes (default ``fp32``; :func:`toolpath.inference.qat.fp32_twin`)."""
    from toolpath.pipeline import artifacts

    variants: dict = {"torch_fp32": fp32.eval()}
    sizes: dict = {"errors": {}}
    sizes["onnx_fp32_bytes"] = export_onnx(fp32 if onnx_fp32 is None else onnx_fp32, example, workdir / "fp32.onnx")
    files = {"fp32": workdir / "fp32.onnx"}
    if int8_file is not None:
        int8 = artifacts.load_int8(int8_file)
        variants["torch_int8"] = int8
        sizes["onnx_int8_bytes"] = export_onnx(load_int8_program(int8_file), example, workdir / "int8.onnx")
        files["int8"] = workdir / "int8.onnx"
    for runtime, make in (("onnxruntime", onnxruntime_runner), ("openvino", openvino_runner)):
        for precision, file in files.items():
            try:
                variants[f"{runtime}_{precision}"] = make(file, threads)
            except Exception as exc:  # a runtime that refuses a graph is a finding, not a crash
                sizes["errors"][f"{runtime}_{precision}"] = f"{type(exc).__name__}: {str(exc)[:300]}"
    if calibration is not None:
        try:
            sizes["onnx_ptq_bytes"] = static_int8(files["fp32"], calibration, workdir / "ptq.onnx")
            variants["onnxruntime_ptq"] = onnxruntime_runner(workdir / "ptq.onnx", threads)
        except Exception as exc:  # noqa: BLE001 - as above
            sizes["errors"]["onnxruntime_ptq"] = f"{type(exc).__name__}: {str(exc)[:300]}"
    return variants, sizes


def compare(name: str, fp32: torch.nn.Module, int8_file: Path | None, test: tuple[torch.Tensor, np.ndarray],
            inputs: dict[str, torch.Tensor], threads: int, repeats: int, warmup: int = 2,
            calibration: np.ndarray | None = None, onnx_fp32: torch.nn.Module | None = None) -> dict:
    """Timings, speed-ups and test accuracies of every variant of one model (module docstring)."""
    from toolpath.inference.timing import timed

    with tempfile.TemporaryDirectory(prefix=f"runtimes-{name}-") as tmp:
        variants, sizes = runners(fp32, int8_file, inputs["batch"][:2], threads, Path(tmp), calibration, onnx_fp32)
        with torch.inference_mode():
            accuracy = {v: float((np.asarray(_logits(run, test[0])).argmax(1) == test[1]).mean())
                        for v, run in variants.items()}
        seconds = timed(variants, inputs, repeats, warmup, warm=inputs["batch"])
        if (Path(tmp) / "int8.onnx").is_file():  # why INT8 is or is not faster: what stays float
            sizes["onnxruntime_int8_op_profile"] = op_profile(Path(tmp) / "int8.onnx", "onnxruntime", threads,
                                                              inputs["batch"].numpy(), runs=20)
        if "onnxruntime_ptq" in variants:
            sizes["onnxruntime_ptq_op_profile"] = op_profile(Path(tmp) / "ptq.onnx", "onnxruntime", threads,
                                                             inputs["batch"].numpy(), runs=20)
    batch = len(inputs["batch"])
    rows = {v: {"latency_b1_ms": 1e3 * s["b1"], "windows_per_s": batch / s["batch"], "test_accuracy": accuracy[v]}
            for v, s in seconds.items()}
    fastest_fp32 = max((r["windows_per_s"], v) for v, r in rows.items() if v.endswith("_fp32"))
    for runtime in RUNTIMES:
        if f"{runtime}_int8" in rows and f"{runtime}_fp32" in rows:
            row = rows[f"{runtime}_int8"]
            row["speedup_same_runtime"] = row["windows_per_s"] / rows[f"{runtime}_fp32"]["windows_per_s"]
            row["speedup_vs_fastest_fp32"] = row["windows_per_s"] / fastest_fp32[0]
            # a fast INT8 graph that lost its accuracy is no candidate (issue 22: within 1 point)
            row["accuracy_drop_points"] = 100.0 * (rows[f"{runtime}_fp32"]["test_accuracy"] - row["test_accuracy"])
    if "onnxruntime_ptq" in rows and "onnxruntime_fp32" in rows:
        row, fp32_row = rows["onnxruntime_ptq"], rows["onnxruntime_fp32"]
        row["speedup_same_runtime"] = row["windows_per_s"] / fp32_row["windows_per_s"]
        row["speedup_vs_fastest_fp32"] = row["windows_per_s"] / fastest_fp32[0]
        row["accuracy_drop_points"] = 100.0 * (fp32_row["test_accuracy"] - row["test_accuracy"])
    return {"variants": rows, "fastest_fp32": fastest_fp32[1], **sizes}


def _logits(run, x: torch.Tensor, chunk: int = 1024) -> np.ndarray:
    outs = [run(x[i:i + chunk]) for i in range(0, len(x), chunk)]
    return np.concatenate([o.detach().numpy() if isinstance(o, torch.Tensor) else np.asarray(o) for o in outs])


def measure(models: list[str], shape: str, threads: int, repeats: int, batch: int = 256, seed: int = 0) -> dict:
    """:func:`compare` for each model of ``models`` on ``shape``'s pipeline artefacts (``make repro`` first)."""
    from toolpath.inference.qat import fp32_twin
    from toolpath.inference.timing import machine
    from toolpath.pipeline import artifacts, config, settings
    from toolpath.pipeline.artifacts import Split

    cfg = config.load()
    layout = settings.layout(cfg)
    data = artifacts.load_windows(layout.windows_file(shape), shape)
    windows, labels = data.part(Split.TEST)
    test = (torch.as_tensor(windows, dtype=torch.float32), artifacts.category_index(labels))
    calibration = data.part(Split.TRAIN)[0][:1024]  # the first training windows: no test window calibrates
    pick = torch.randint(0, len(test[0]), (batch,), generator=torch.Generator().manual_seed(seed))
    inputs = {"b1": test[0][pick[:1]], "batch": test[0][pick]}
    torch.set_num_threads(threads)
    out: dict = {"machine": machine(threads), "shape": shape, "batch": batch, "repeats": repeats, "models": {}}
    for name in models:
        fp32 = artifacts.load_classifier(layout.checkpoint(shape, name), f"train@{name}").network_
        int8_file = layout.int8_model(shape, name)
        twin = fp32_twin(fp32, settings.float_modules(cfg, name), bool(cfg.qat.quantize_conv1d))
        out["models"][name] = compare(name, fp32, int8_file if int8_file.is_file() else None, test, inputs,
                                      threads, repeats, calibration=calibration, onnx_fp32=twin)
        out["models"][name]["fp32_checkpoint_bytes"] = layout.checkpoint(shape, name).stat().st_size
        if int8_file.is_file():
            out["models"][name]["int8_pt2_bytes"] = int8_file.stat().st_size
    return out
