"""The INT8 runtimes of toolpath.bench.runtimes on a QAT-trained MLP: the same ONNX files run in ONNX Runtime
and OpenVINO and agree with torch (no timing here: speed lives in `make bench`)."""

import numpy as np
import pytest
import torch

from toolpath.inference import qat
from toolpath.models.training.loop import TrainSettings, predict_logits

pytest.importorskip("onnxruntime", reason="the `runtimes` extra of pyproject.toml is not installed")
pytest.importorskip("openvino", reason="the `runtimes` extra of pyproject.toml is not installed")

from toolpath.bench import runtimes  # noqa: E402
from toolpath.inference import runtimes as onnx_runtimes  # noqa: E402


@pytest.fixture(scope="module")
def int8_file(trained_mlp, tmp_path_factory):
    clf, X, y = trained_mlp
    result = qat.train_qat(clf.network_, X, y, TrainSettings(lr=3e-4, epochs=2, batch_size=32, seed=2), X, y,
                           freeze_last=1, float_modules=("prepare", "net.0"))
    path = tmp_path_factory.mktemp("int8") / "mlp.pt2"
    qat.save(result.model, torch.as_tensor(X[:2]), path)
    return path


def test_fp32_onnx_gives_torch_logits_in_both_runtimes(trained_mlp, tmp_path, monkeypatch):
    """An FP32 file gives torch's logits in both runtimes; where export_onnx cannot keep torch.onnx's torchlib
    table (its module cannot be imported: another torch's internals), the exporter builds its own: the same bytes."""
    import sys

    clf, X, _ = trained_mlp
    x = torch.as_tensor(X)
    size = runtimes.export_onnx(clf.network_, x[:2], tmp_path / "fp32.onnx")
    weights = sum(p.numel() for p in clf.network_.parameters())
    assert size > 4 * weights and [f.name for f in tmp_path.iterdir()] == ["fp32.onnx"]  # FP32 weights inside
    expected = predict_logits(clf.network_, x).numpy()
    for make in (runtimes.onnxruntime_runner, runtimes.openvino_runner):
        got = make(tmp_path / "fp32.onnx", 1)(x)
        np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-4)
    monkeypatch.setitem(sys.modules, "torch.onnx._internal.exporter._registration", None)  # torch keeps its own
    runtimes.export_onnx(clf.network_, x[:2], tmp_path / "own" / "fp32.onnx")
    assert (tmp_path / "own" / "fp32.onnx").read_bytes() == (tmp_path / "fp32.onnx").read_bytes()


def test_int8_onnx_runs_the_qat_scales_in_both_runtimes(trained_mlp, int8_file, tmp_path):
    _, X, y = trained_mlp
    x = torch.as_tensor(X)
    reference = qat.load(int8_file)
    expected = predict_logits(reference, x).argmax(1).numpy()
    runtimes.export_onnx(runtimes.load_int8_program(int8_file), x[:2], tmp_path / "int8.onnx")
    for make in (runtimes.onnxruntime_runner, runtimes.openvino_runner):
        got = np.asarray(make(tmp_path / "int8.onnx", 1)(x)).argmax(1)
        assert (got == expected).mean() >= 0.95  # INT8 kernels round differently from the reference graph
        assert (got == y).mean() >= 0.9  # and the split is easy: the model still separates it


def test_compare_reports_every_variant_with_accuracy_and_speedups(trained_mlp, int8_file):
    clf, X, y = trained_mlp
    x = torch.as_tensor(X)
    out = runtimes.compare("mlp", clf.network_, int8_file, (x, y), {"b1": x[:1], "batch": x[:64]}, threads=1,
                           repeats=1, warmup=0)
    assert set(out["variants"]) == {f"{r}_{p}" for r in runtimes.RUNTIMES for p in ("fp32", "int8")}
    assert not out["errors"] and out["onnx_int8_bytes"] > 0
    assert all(0.9 <= v["test_accuracy"] <= 1 for v in out["variants"].values())
    assert all("speedup_same_runtime" in out["variants"][f"{r}_int8"] for r in runtimes.RUNTIMES)
    assert all(abs(out["variants"][f"{r}_int8"]["accuracy_drop_points"]) <= 10 for r in runtimes.RUNTIMES)
    profile = out["onnxruntime_int8_op_profile"]  # what the INT8 graph spends its time on, by operator
    assert sum(profile["share_by_kind"].values()) == pytest.approx(1.0)
    assert sum(profile["share_by_op"].values()) == pytest.approx(1.0)
    assert profile["share_by_kind"]["integer"] > 0  # the MLP's quantised linears run as integer kernels


def test_static_int8_quantises_every_matrix_op_but_the_first_with_its_output(trained_mlp, tmp_path):
    import onnx

    clf, X, y = trained_mlp
    x = torch.as_tensor(X)
    runtimes.export_onnx(clf.network_, x[:2], tmp_path / "fp32.onnx")
    assert runtimes.static_int8(tmp_path / "fp32.onnx", X[:128], tmp_path / "ptq.onnx") > 0
    graph = onnx.load(str(tmp_path / "ptq.onnx")).graph
    producer = {out: node.op_type for node in graph.node for out in node.output}
    consumers = {}
    for node in graph.node:
        for name in node.input:
            consumers.setdefault(name, []).append(node.op_type)
    matrix = [n for n in graph.node if n.op_type in runtimes.QUANTIZED_OPS]
    assert len(matrix) >= 2
    assert all(producer.get(name) != "DequantizeLinear" for name in matrix[0].input)  # the first stays float
    for node in matrix[1:]:  # the rest: int8 in and out, which ONNX Runtime fuses into one QLinear kernel
        assert producer.get(node.input[0]) == "DequantizeLinear" and producer.get(node.input[1]) == "DequantizeLinear"
        assert consumers[node.output[0]] == ["QuantizeLinear"]
    out = runtimes.compare("mlp", clf.network_, None, (x, y), {"b1": x[:1], "batch": x[:64]}, threads=1,
                           repeats=1, warmup=0, calibration=X[:128])
    row = out["variants"]["onnxruntime_ptq"]
    assert row["test_accuracy"] >= 0.9 and {"speedup_same_runtime", "speedup_vs_fastest_fp32"} <= set(row)
    assert out["onnxruntime_ptq_op_profile"]["share_by_kind"]["integer"] > 0


def test_op_kind_reads_both_runtimes_operator_names():
    assert [onnx_runtimes.op_kind(op) for op in ("QLinearConv", "MatMulInteger", "DequantizeLinear", "Gelu")] == \
        ["integer", "integer", "convert", "float"]
    assert [onnx_runtimes.op_kind(op) for op in ("FullyConnected [jit_gemm_I8]", "FakeQuantize [jit_avx2_f32]",
                                             "Reorder [jit_uni_I8]", "FullyConnected [brgemm_avx2_f32]")] == \
        ["integer", "convert", "convert", "float"]


@pytest.mark.parametrize("runtime", onnx_runtimes.RUNTIMES)
def test_op_profile_splits_an_int8_files_time_by_operator_and_kind(trained_mlp, int8_file, tmp_path, runtime):
    _, X, _ = trained_mlp
    x = torch.as_tensor(X[:64])
    runtimes.export_onnx(runtimes.load_int8_program(int8_file), x[:2], tmp_path / "int8.onnx")
    profile = onnx_runtimes.op_profile(tmp_path / "int8.onnx", runtime, 1, x.numpy(), runs=2, top=3)
    assert profile["ms_per_run"] > 0 and profile["runs"] == 2 and profile["batch"] == 64
    assert len(profile["share_by_op"]) <= 4 and sum(profile["share_by_op"].values()) == pytest.approx(1.0)
    assert sum(profile["share_by_kind"].values()) == pytest.approx(1.0)
    assert profile["share_by_kind"]["integer"] > 0  # the MLP's quantised linears run as integer kernels
    with pytest.raises(ValueError, match="runtime must be one of"):
        onnx_runtimes.op_profile(tmp_path / "int8.onnx", "tvm", 1, x.numpy())


def test_smooth_classifier_runs_an_onnx_file_in_either_runtime(trained_mlp, tmp_path):
    from toolpath.inference import runtimes as shipped_runtimes
    from toolpath.smooth.command import classifier

    clf, X, _ = trained_mlp
    x = torch.as_tensor(X)
    runtimes.export_onnx(clf.network_, x[:2], tmp_path / "mlp.fp32.onnx")
    expected = predict_logits(clf.network_, x).argmax(1).numpy() + 1
    for runtime in shipped_runtimes.RUNTIMES:
        assert (classifier(str(tmp_path / "mlp.fp32.onnx"), runtime)(X) == expected).mean() >= 0.99


def test_score_gives_each_runtime_its_metrics_and_int8_drop(trained_mlp, int8_file, tmp_path):
    from toolpath.inference import runtimes as shipped_runtimes
    from toolpath.models.rule import CLASSES
    from toolpath.models.training.metrics import classification_metrics

    def metrics(t, p):
        return classification_metrics(CLASSES[t], p)

    clf, X, y = trained_mlp
    size = shipped_runtimes.export_int8(int8_file, torch.as_tensor(X[:2]), tmp_path / "mlp.onnx")
    again = shipped_runtimes.export_int8(int8_file, torch.as_tensor(X[:2]), tmp_path / "again.onnx")
    assert size == again and (tmp_path / "again.onnx").read_bytes() == (tmp_path / "mlp.onnx").read_bytes()
    reference = predict_logits(qat.load(int8_file), torch.as_tensor(X)).argmax(1).numpy()
    fp32 = float((predict_logits(clf.network_, torch.as_tensor(X)).argmax(1).numpy() == y).mean())
    out = shipped_runtimes.score(tmp_path / "mlp.onnx", X, y, reference, fp32, 1, metrics)
    for runtime in shipped_runtimes.RUNTIMES:
        row = out[runtime]
        assert row["accuracy_drop_points"] == pytest.approx(100 * (fp32 - row["int8"]["accuracy"]))
        assert row["int8_agrees_with_pt2"] >= 0.95 and row["int8"]["accuracy"] >= 0.9
    (tmp_path / "mlp.onnx").write_bytes(b"not onnx")  # a runtime refusing a file is recorded, not raised
    broken = shipped_runtimes.score(tmp_path / "mlp.onnx", X, y, reference, fp32, 1, metrics)
    assert all(set(broken[r]) == {"error"} for r in shipped_runtimes.RUNTIMES)


def test_score_refuses_figures_a_second_session_does_not_reproduce(monkeypatch):
    """A runtime whose second session of one file gives other logits (OpenVINO's INT8 ConvMixer did)
    gets a reason, not an accuracy that would change from run to run, and so is never shipped."""
    import numpy as np

    from toolpath.inference import runtimes as shipped_runtimes
    from toolpath.inference.timing import shipped

    sessions = {"onnxruntime": 0, "openvino": 0}

    def runner(path, runtime, threads):
        sessions[runtime] += 1
        # ONNX Runtime: the same logits every session; OpenVINO: a different bias per session
        bias = 0.0 if runtime == "onnxruntime" else float(sessions[runtime])
        return lambda x: np.stack([x[:, :, 0].sum(1) + bias, x[:, :, 1].sum(1), np.zeros(len(x)), np.zeros(len(x))], 1)

    monkeypatch.setattr(shipped_runtimes, "runner", runner)
    X = np.random.default_rng(0).normal(size=(40, 50, 2)).astype(np.float32)
    y = np.zeros(40, dtype=int)
    def accuracy_only(t, p):
        return {"accuracy": float((p.argmax(1) == t).mean())}

    out = shipped_runtimes.score("any.onnx", X, y, y, 1.0, 1, accuracy_only)
    accuracy = out["onnxruntime"]["int8"]["accuracy"]
    assert out["onnxruntime"]["accuracy_drop_points"] == pytest.approx(100 * (1 - accuracy)) and accuracy < 1
    assert set(out["openvino"]) == {"error"} and "not reproducible" in out["openvino"]["error"]
    entry = {f"{r}_int8": {"windows_per_s": 1.0 + (r == "openvino"), "speedup_vs_fastest_fp32": 1.0}
             for r in shipped_runtimes.RUNTIMES}
    assert shipped(entry, {"gear": {"runtimes": out}}, 100.0)["runtime"] == "onnxruntime"


def test_shipped_runtime_is_the_fastest_int8_within_the_accuracy_bound():
    from toolpath.inference.timing import shipped

    entry = {"onnxruntime_int8": {"windows_per_s": 200.0, "speedup_vs_fastest_fp32": 1.2},
             "openvino_int8": {"windows_per_s": 300.0, "speedup_vs_fastest_fp32": 1.8},
             "int8_speedup_onnxruntime": 1.3, "int8_speedup_openvino": 2.0}
    qat_entries = {"gear": {"runtimes": {"onnxruntime": {"accuracy_drop_points": 0.2},
                                         "openvino": {"accuracy_drop_points": 0.9}}},
                   "maple_leaf": {"runtimes": {"onnxruntime": {"accuracy_drop_points": -0.1},
                                               "openvino": {"accuracy_drop_points": 0.4}}}}
    assert shipped(entry, qat_entries, 1.0)["runtime"] == "openvino"
    assert shipped(entry, qat_entries, 0.5) == {"runtime": "onnxruntime", "speedup_same_runtime": 1.3,
                                                "speedup_vs_fastest_fp32": 1.2,
                                                "accuracy_drop_points": {"gear": 0.2, "maple_leaf": -0.1}}
    none = shipped(entry, qat_entries, 0.1)
    assert none["runtime"] is None and "within 0.1 points" in none["why"]


def test_int8_dot_product_names_the_instruction_from_the_cpu_flags():
    from toolpath.inference.timing import int8_dot_product

    assert int8_dot_product({"avx2", "fma"}) == "none (AVX2: vpmaddubsw)"
    assert int8_dot_product({"avx2", "avx512f", "avx512_vnni"}) == "AVX512-VNNI"
    assert int8_dot_product({"avx2", "avx_vnni"}) == "AVX-VNNI"
    assert int8_dot_product({"sse2"}) == "none"


def test_integer_kernel_ceiling_times_true_products_in_both_precisions():
    """The two graphs `make bench` races compute the same shape of product: the integer one exactly
    (int32 out), the float one to float precision; the record names both times and their ratio."""
    import numpy as np
    import onnx
    from onnx import numpy_helper

    from toolpath.bench import kernels

    rng = np.random.default_rng(1)
    for integer, x in ((True, rng.integers(0, 128, (5, 16), dtype=np.uint8)),
                       (False, rng.standard_normal((5, 16)).astype(np.float32))):
        model = kernels._model(16, 8, integer, seed=3)
        weight = numpy_helper.to_array(onnx.load_from_string(model).graph.initializer[0])
        got = kernels._session(model, 1)(x)
        expected = x.astype(np.int64) @ weight.astype(np.int64) if integer else x @ weight
        assert np.allclose(got, expected, rtol=1e-5, atol=1e-4) and got.dtype == (np.int32 if integer else np.float32)
    record = kernels.measure(1, 1, shapes=((4, 16, 8),))
    row = record["shapes"]["4x16x8"]
    assert row["fp32_over_int8"] == row["fp32_ms"] / row["int8_ms"] and record["int8_dot_product"]
