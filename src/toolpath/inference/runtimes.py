"""Our models in the two ONNX runtimes Table 4 ships for: ONNX Runtime and OpenVINO.

The qat stage exports each QAT INT8 graph (the PT2E program of the ``.pt2``, its learned scales
included) to ONNX (``torch.onnx.export(..., dynamo=True)``, the weights inside the one file), which
becomes a QDQ model: ONNX Runtime fuses its quantize / dequantize pairs into integer kernels where it
can, OpenVINO's CPU plugin likewise.  One INT8 file runs in both runtimes, so the accuracy scored here
is the accuracy of the artefact the benchmark times and ``toolpath smooth --classifier MODEL.onnx``
loads.  The benchmark stage exports the FP32 networks the same way to time them beside it.
OpenVINO is compiled with f32 as its inference precision: its default on this CPU, bf16, changes FP32 predictions.
"""

from __future__ import annotations

import copy
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch

RUNTIMES = ("onnxruntime", "openvino")
REPRODUCIBILITY_CHECK = 1024  # test windows a second session of an INT8 file must reproduce bit for bit
PRECISIONS = ("fp32", "int8")
Runner = Callable[[np.ndarray], np.ndarray]


def export_onnx(model: torch.nn.Module | torch.export.ExportedProgram, example: torch.Tensor, path: Path,
                translations: dict | None = None) -> int:
    """``model`` (a network, or an exported program such as a QAT INT8 graph) as one ONNX file with a
    dynamic batch dimension; returns its size in bytes.  The same model gives the same bytes.
    ``translations``: ONNX translations of torch ops beside the exporter's own; by default
    :data:`toolpath.inference.recurrences.STEPWISE` (tanh RNNs step by step, lean), ``{}`` for the
    exporter's own (e.g. :data:`toolpath.inference.recurrences.TRANSLATIONS`: RNN nodes)."""
    import logging

    if translations is None:
        from toolpath.inference.recurrences import STEPWISE as translations

    logging.getLogger("torch.onnx").setLevel(logging.ERROR)  # "torchvision is not installed", per export
    path.parent.mkdir(parents=True, exist_ok=True)
    batch = torch.export.Dim("batch", min=1, max=1 << 16)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the exporter's deprecation and opset notes
        if isinstance(model, torch.export.ExportedProgram):
            program = model
        else:
            program = torch.export.export(model.eval(), (example,), dynamic_shapes=({0: batch},))
        with _torchlib_table_kept():
            exported = torch.onnx.export(program, dynamo=True, input_names=["windows"], output_names=["logits"],
                                         verbose=False, custom_translation_table=translations)
    _strip_provenance(exported.model)
    exported.save(str(path), external_data=False)  # the weights inside the one file
    return path.stat().st_size


_TORCHLIB_TABLES: dict = {}


@contextmanager
def _torchlib_table_kept() -> Iterator[None]:
    """torch.onnx's exporter builds its table of ONNX functions from torchlib at every export (about 2 s:
    most of a small network's export), though the table depends only on the opset.  Inside this block it
    is built once per process and opset, and each export gets a copy of its own (the exporter adds the
    custom translations to it).  With another torch's internals, the exporter runs as it is."""
    try:
        from torch.onnx._internal.exporter._registration import ONNXRegistry

        build = ONNXRegistry.__dict__["from_torchlib"]
    except (ImportError, KeyError):
        yield
        return

    def kept(cls, *args, **kwargs):
        key = (cls, args, tuple(sorted(kwargs.items())))
        if key not in _TORCHLIB_TABLES:
            _TORCHLIB_TABLES[key] = build.__func__(cls, *args, **kwargs)
        table = copy.copy(_TORCHLIB_TABLES[key])
        table.functions = {op: list(functions) for op, functions in table.functions.items()}
        return table

    ONNXRegistry.from_torchlib = classmethod(kept)
    try:
        yield
    finally:
        ONNXRegistry.from_torchlib = build


def _strip_provenance(model) -> None:
    """Drop each node's provenance (the torch op, module path and Python stack trace it came from): a
    debugging aid of several hundred bytes a node, most of an unrolled recurrence's file, whose stack
    traces name this checkout's absolute paths (so a file would differ from one clone to another)."""
    for node in model.graph.all_nodes():
        node.metadata_props.clear()
        node.doc_string = None


def load_int8_program(path: Path) -> torch.export.ExportedProgram:
    """The PT2E program of a ``.pt2`` INT8 file (the quantize / dequantize ops it uses registered)."""
    import logging

    logging.getLogger("torchao").setLevel(logging.ERROR)  # its optional CUDA kernels: noise on a CPU
    import torchao.quantization.pt2e  # noqa: F401

    return torch.export.load(str(path))


def onnxruntime_runner(path: Path, threads: int) -> Runner:
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads, options.inter_op_num_threads = threads, 1
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.log_severity_level = 3  # errors only: its notes on unused initialisers are not ours to act on
    session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
    name = session.get_inputs()[0].name
    return lambda x: session.run(None, {name: np.ascontiguousarray(x, dtype=np.float32)})[0]


def openvino_runner(path: Path, threads: int) -> Runner:
    import openvino as ov  # telemetry lives in its model converters, which this does not use; make opts out

    core = ov.Core()
    compiled = core.compile_model(str(path), "CPU", {"INFERENCE_NUM_THREADS": threads, "NUM_STREAMS": 1,
                                                     "INFERENCE_PRECISION_HINT": "f32",
                                                     "PERFORMANCE_HINT": "LATENCY"})
    request = compiled.create_infer_request()
    return lambda x: np.array(request.infer({0: np.ascontiguousarray(x, dtype=np.float32)})[0])


# what each operator of a profile computes in: ONNX Runtime names its integer kernels and conversions;
# OpenVINO names the kernel's precision in its exec type (jit_gemm_I8) and converts in FakeQuantize / Reorder
KINDS = ("integer", "convert", "float")
ORT_INTEGER_OPS = ("QLinear", "ConvInteger", "MatMulInteger", "DynamicQuantize", "QGemm", "QAttention")
ORT_CONVERT_OPS = ("QuantizeLinear", "DequantizeLinear")
OV_CONVERT_OPS = ("FakeQuantize", "Reorder", "Convert")


def op_kind(op: str) -> str:
    """``integer``, ``convert`` or ``float`` for an operator of :func:`op_profile` (ONNX Runtime's
    ``QLinearConv``, OpenVINO's ``FullyConnected [jit_gemm_I8]``)."""
    if "[" in op:  # OpenVINO: node type [exec type]
        node, exec_type = op.rstrip("]").split(" [", 1)
        return "convert" if node in OV_CONVERT_OPS else "integer" if "I8" in exec_type.upper() else "float"
    return "integer" if op.startswith(ORT_INTEGER_OPS) else "convert" if op in ORT_CONVERT_OPS else "float"


def op_profile(path: Path, runtime: str, threads: int, batch: np.ndarray, runs: int = 10, top: int = 8) -> dict:
    """Where ``runtime`` spends the time of the ONNX file ``path`` on ``batch``, from its own profiler
    (after its graph optimisations fused what they could): milliseconds per run, the ``top`` operators'
    shares (the rest as ``other``) and the shares of integer kernels, conversions and float operators,
    the part INT8 leaves unquantised: why an INT8 file is or is not faster."""
    if runtime not in RUNTIMES:
        raise ValueError(f"runtime must be one of {RUNTIMES}, got {runtime!r}")
    batch = np.ascontiguousarray(batch, dtype=np.float32)
    micros = (_onnxruntime_micros if runtime == "onnxruntime" else _openvino_micros)(Path(path), threads, batch, runs)
    total = sum(micros.values()) or 1.0
    ranked = sorted(micros.items(), key=lambda kv: -kv[1])
    shares = {op: us / total for op, us in ranked[:top]}
    if len(ranked) > top:
        shares["other"] = sum(us for _, us in ranked[top:]) / total
    return {"runs": runs, "batch": len(batch), "ms_per_run": total / runs / 1e3, "share_by_op": shares,
            "share_by_kind": {k: sum(us for op, us in micros.items() if op_kind(op) == k) / total for k in KINDS}}


def _onnxruntime_micros(path: Path, threads: int, batch: np.ndarray, runs: int) -> dict[str, float]:
    import json
    import tempfile

    import onnxruntime as ort

    with tempfile.TemporaryDirectory(prefix="ort-profile-") as tmp:
        options = ort.SessionOptions()
        options.intra_op_num_threads, options.inter_op_num_threads = threads, 1
        options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        options.log_severity_level = 3
        options.enable_profiling, options.profile_file_prefix = True, str(Path(tmp) / "ort")
        session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        feed = {session.get_inputs()[0].name: batch}
        for _ in range(runs + 1):
            session.run(None, feed)
        events = json.loads(Path(session.end_profiling()).read_text())
    # the first run is a warm-up (buffers allocated, kernels chosen): only the nodes after it count
    first = min((e for e in events if e.get("name") == "model_run"), key=lambda e: e["ts"])
    warm_end = first["ts"] + first["dur"]
    micros: dict[str, float] = {}
    for event in events:
        if event.get("cat") == "Node" and str(event.get("name", "")).endswith("_kernel_time") and \
                event["ts"] >= warm_end:
            op = event["args"]["op_name"]
            micros[op] = micros.get(op, 0.0) + event["dur"]
    return micros


def _openvino_micros(path: Path, threads: int, batch: np.ndarray, runs: int) -> dict[str, float]:
    import openvino as ov

    compiled = ov.Core().compile_model(str(path), "CPU", {"INFERENCE_NUM_THREADS": threads, "NUM_STREAMS": 1,
                                                          "INFERENCE_PRECISION_HINT": "f32",
                                                          "PERFORMANCE_HINT": "LATENCY", "PERF_COUNT": True})
    request = compiled.create_infer_request()
    request.infer({0: batch})  # warm-up: its counters are the last call's, so it is not counted
    micros: dict[str, float] = {}
    for _ in range(runs):
        request.infer({0: batch})
        for node in request.profiling_info:
            op = f"{node.node_type} [{node.exec_type}]"
            micros[op] = micros.get(op, 0.0) + node.real_time.total_seconds() * 1e6
    return micros


def runner(path: Path, runtime: str, threads: int) -> Runner:
    """A function from (B, 50, 2) float32 windows to (B, 4) logits, running ``path`` in ``runtime``."""
    if runtime not in RUNTIMES:
        raise ValueError(f"runtime must be one of {RUNTIMES}, got {runtime!r}")
    return (onnxruntime_runner if runtime == "onnxruntime" else openvino_runner)(Path(path), threads)


def logits(run: Runner, X: np.ndarray, chunk: int = 1024) -> np.ndarray:
    """``run`` over ``X`` in chunks of ``chunk`` windows."""
    X = np.asarray(X, dtype=np.float32)
    return np.concatenate([run(X[i:i + chunk]) for i in range(0, len(X), chunk)]) if len(X) else np.zeros((0, 4))


def export_int8(int8_program: Path, example: torch.Tensor, path: Path) -> int:
    """The INT8 ``.pt2`` program (the QAT graph with its learned scales) as an ONNX QDQ file; its size."""
    return export_onnx(load_int8_program(int8_program), example, path)


def score(int8_file: Path, X: np.ndarray, y: np.ndarray, reference: np.ndarray, fp32_accuracy: float, threads: int,
          metrics: Callable[[np.ndarray, np.ndarray], dict]) -> dict:
    """The INT8 ONNX file in every runtime on a test split: its Table 3 ``metrics(y, probabilities)``,
    its accuracy drop in points against the FP32 network's ``fp32_accuracy`` (the model as trained:
    what shipping INT8 in that runtime costs), and how often it agrees with ``reference`` (the ``.pt2``
    graph's predictions).  A runtime that cannot run the file, or whose second session of it does not
    reproduce the first one's logits, is a finding, recorded with its reason instead of figures."""
    out: dict = {}
    for runtime in RUNTIMES:
        try:
            z = logits(runner(int8_file, runtime, threads), X)
            # a second session of the same file must give the same logits: OpenVINO's INT8 ConvMixer
            # did not (up to 65 logits apart, 2-3 points of accuracy between two runs of one seed)
            again = logits(runner(int8_file, runtime, threads), X[:REPRODUCIBILITY_CHECK])
        except Exception as exc:  # noqa: BLE001 - a runtime refusing a graph is reported, not raised
            out[runtime] = {"error": f"{type(exc).__name__}: {str(exc)[:300]}"}
            continue
        if not np.array_equal(again, z[:REPRODUCIBILITY_CHECK]):
            # its accuracy would be a different number every run: not a result, and never shipped
            out[runtime] = {"error": f"not reproducible: two sessions of this file disagree on the first "
                                     f"{min(len(X), REPRODUCIBILITY_CHECK)} test windows"}
            continue
        z = np.exp(z - z.max(axis=1, keepdims=True))
        proba = z / z.sum(axis=1, keepdims=True)
        row = {"int8": metrics(y, proba), "int8_agrees_with_pt2": float((proba.argmax(1) == reference).mean())}
        row["accuracy_drop_points"] = 100.0 * (fp32_accuracy - row["int8"]["accuracy"])
        out[runtime] = row
    return out
