"""The most an INT8 kernel can gain over FP32 on this CPU: one matrix product in ONNX Runtime, both ways.

Per shape ``(M, K, N)``: ``MatMul`` on float32 against ``MatMulInteger`` (uint8 activations on 7 bits,
as ``qat.reduce_range`` ships them, times int8 weights, int32 out: the integer core of every QGemm /
QLinearConv / MatMulIntegerToFloat, with no quantize or dequantize step around it).  A model's INT8
file cannot beat its FP32 file by more than this ratio on its matrix products, and the rest of the
model (element-wise ops, pooling, normalisation, recurrences) stays float.  On x86 with VNNI
(``vpdpbusd``) the ratio is typically 2-4x; with AVX2 alone the products go through ``vpmaddubsw``
+ ``vpmaddwd`` and gain far less.  The shapes are the models' own: the CNN's 800 -> 512 layer, a
ConvNeXt block's 96 -> 384 expansion over 256 windows x 12 points, a ConvMixer pointwise convolution
(192 -> 192 over 256 x 25 points) and MCRL's 128-wide recurrent step.
"""

from __future__ import annotations

import numpy as np
import torch

SHAPES = ((256, 800, 512), (3072, 96, 384), (6400, 192, 192), (256, 128, 128))


def _model(k: int, n: int, integer: bool, seed: int) -> bytes:
    from onnx import TensorProto, helper, numpy_helper

    rng = np.random.default_rng(seed)
    if integer:
        weight = numpy_helper.from_array(rng.integers(-127, 128, (k, n), dtype=np.int8), "w")
        node = helper.make_node("MatMulInteger", ["x", "w"], ["y"])
        x_type, y_type = TensorProto.UINT8, TensorProto.INT32
    else:
        weight = numpy_helper.from_array(rng.standard_normal((k, n)).astype(np.float32), "w")
        node = helper.make_node("MatMul", ["x", "w"], ["y"])
        x_type, y_type = TensorProto.FLOAT, TensorProto.FLOAT
    graph = helper.make_graph([node], "product", [helper.make_tensor_value_info("x", x_type, [None, k])],
                              [helper.make_tensor_value_info("y", y_type, [None, n])], [weight])
    return helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)]).SerializeToString()


def _session(model: bytes, threads: int):
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads, options.inter_op_num_threads = threads, 1
    options.log_severity_level = 3
    session = ort.InferenceSession(model, options, providers=["CPUExecutionProvider"])
    return lambda x: session.run(None, {"x": x})[0]


def measure(threads: int, repeats: int, shapes: tuple[tuple[int, int, int], ...] = SHAPES, seed: int = 0) -> dict:
    """Per shape: FP32 ``MatMul`` and INT8 ``MatMulInteger`` milliseconds (medians of interleaved
    repetitions, :func:`toolpath.inference.timing.timed`) and their ratio, FP32 / INT8."""
    from toolpath.inference.timing import int8_dot_product, timed

    rng = np.random.default_rng(seed)
    out: dict = {"int8_dot_product": int8_dot_product(), "threads": threads, "repeats": repeats, "shapes": {}}
    for m, k, n in shapes:
        runners = {"fp32": _session(_model(k, n, False, seed), threads),
                   "int8": _session(_model(k, n, True, seed), threads)}
        inputs = {"fp32": rng.standard_normal((m, k)).astype(np.float32),
                  "int8": rng.integers(0, 128, (m, k), dtype=np.uint8)}
        # each runner takes its own input type: time them as one-input runners of a shared dummy
        wrapped = {p: (lambda _x, run=run, x=inputs[p]: run(x)) for p, run in runners.items()}
        seconds = timed(wrapped, {"product": torch.zeros(1)}, repeats, warmup=3)
        fp32, int8 = seconds["fp32"]["product"], seconds["int8"]["product"]
        out["shapes"][f"{m}x{k}x{n}"] = {"fp32_ms": 1e3 * fp32, "int8_ms": 1e3 * int8, "fp32_over_int8": fp32 / int8,
                                        "fp32_gflops": 2 * m * k * n / fp32 / 1e9}
    return out
