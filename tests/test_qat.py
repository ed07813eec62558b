"""QAT through PT2E on an easy split, the saved INT8 graph, and the benchmark helpers (no torch.compile)."""

import pytest
import torch

from conftest import REPO, easy_split
from toolpath.inference import qat
from toolpath.inference.timing import MCRL_GROUPS, branch_profile, timed
from toolpath.models import MCRL
from toolpath.models.training.loop import TrainSettings, predict_logits


def test_qat_keeps_accuracy_saves_int8_and_reloads_identically(trained_mlp, tmp_path):
    clf, X, y = trained_mlp
    Xt = torch.as_tensor(X)
    fp32 = float((predict_logits(clf.network_, Xt).argmax(1).numpy() == y).mean())
    assert fp32 >= 0.95  # the split is easy: the tolerance below is meaningful
    result = qat.train_qat(clf.network_, X, y, TrainSettings(lr=3e-4, epochs=2, batch_size=32, seed=2), X, y,
                           freeze_last=1)
    int8 = float((predict_logits(result.model, Xt).argmax(1).numpy() == y).mean())
    assert int8 >= fp32 - 0.02  # stated tolerance: 2 points on this split
    ops = qat.op_precision(result.model)
    assert ops["int8"].get("linear", 0) == 5 and not ops["float"]  # every MLP layer runs INT8
    size = qat.save(result.model, Xt[:2], tmp_path / "mlp.pt2")
    assert size > 0
    qat.save(result.model, Xt[:2], tmp_path / "again" / "mlp.pt2")  # a second export of the same model
    assert (tmp_path / "again" / "mlp.pt2").read_bytes() == (tmp_path / "mlp.pt2").read_bytes()
    assert str(REPO) not in (tmp_path / "mlp.pt2").read_bytes().decode("latin-1")  # no checkout's paths inside
    reloaded = qat.load(tmp_path / "mlp.pt2")
    assert torch.equal(predict_logits(reloaded, Xt), predict_logits(result.model, Xt))
    tensors = qat.tensor_bytes(result.model)
    assert tensors["int8"] > 3 * tensors.get("float32", 0)  # the FP32 weight copies are gone


def test_qat_refuses_freezing_before_observers_saw_data(trained_mlp):
    clf, X, y = trained_mlp
    with pytest.raises(ValueError, match="observers must see data"):
        qat.train_qat(clf.network_, X, y, TrainSettings(epochs=1), X, y, freeze_last=1)


def test_missing_int8_model_has_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="dvc repro qat"):
        qat.load(tmp_path / "nothing.pt2")


def test_mcrl_keeps_its_recurrent_layers_float_after_qat():
    X, y = easy_split(64)
    net = MCRL(points=(50, 8, 6, 4)).eval()  # the same modules; 6 steps of the first RNN to trace, not 20
    result = qat.train_qat(net, X, y, TrainSettings(lr=1e-4, epochs=2, batch_size=32), X[:8], y[:8], freeze_last=1)
    ops = qat.op_precision(result.model)
    # the fused RNN / LSTM kernels have no INT8 form: every one stays float, one per fused recurrent module of
    # the network (MCRL's first RNN runs its own unrolled steps, linear layers); the linear layers are quantised
    recurrent = [m for m in net.modules() if type(m) in (torch.nn.RNN, torch.nn.LSTM)]
    assert "lstm" not in ops["int8"] and "rnn_tanh" not in ops["int8"]
    assert ops["float"].get("lstm", 0) + ops["float"].get("rnn_tanh", 0) == len(recurrent) > 0
    assert ops["int8"].get("linear", 0) > 0


def test_timed_and_branch_profile_report_every_part():
    net = MCRL().eval()
    x = torch.randn(8, 50, 2).cumsum(1)
    out = timed({"a": net, "b": lambda v: v.sum()}, {"one": x[:1], "many": x}, repeats=2, warmup=1)
    assert set(out) == {"a", "b"} and set(out["a"]) == {"one", "many"} and out["a"]["many"] > 0
    profile = branch_profile(net, x, repeats=2)
    assert set(profile) == {*MCRL_GROUPS, "total", "unattributed"}
    assert sum(profile[g] for g in MCRL_GROUPS) <= profile["total"] * 1.01


def test_timed_opens_each_runners_turn_with_a_pause_and_an_untimed_call(monkeypatch):
    """Another runtime's threads spin on after its call: each turn starts with a pause and a call that
    is not timed."""
    from toolpath.inference import timing as bench

    calls = []
    monkeypatch.setattr(bench.time, "sleep", lambda seconds: calls.append(("pause", seconds)))

    def runner(name):
        return lambda x: calls.append((name, x.shape[0]))

    x = torch.zeros(4, 50, 2)
    timed({"a": runner("a"), "b": runner("b")}, {"one": x[:1], "many": x}, repeats=2, warmup=0, settle=0.25)
    turn = [("pause", 0.25), ("a", 1), ("a", 1), ("a", 4), ("pause", 0.25), ("b", 1), ("b", 1), ("b", 4)]
    assert calls == turn * 2
    calls.clear()
    timed({"a": runner("a")}, {"many": x}, repeats=1, warmup=0, warm=x[:2], settle=0.0)
    assert calls == [("a", 2), ("pause", 0.0), ("a", 2), ("a", 4)]  # the warm-up slice, then it opens the turn



@pytest.mark.parametrize("reference", [True, False])
def test_bench_model_times_the_int8_reference_graph_and_a_large_batch_only_when_asked(monkeypatch, reference):
    """``benchmark.reference_int8: false`` and ``large_batch: null`` (the default profile) leave torch's
    slow INT8 reference graph and the large batch out of the timing; the FP32 rows, the test splits and
    the speed-ups of the other variants stay."""
    from toolpath.inference import timing as bench

    monkeypatch.setattr(bench.time, "sleep", lambda seconds: None)
    net = torch.nn.Sequential(torch.nn.Flatten(), torch.nn.Linear(100, 4)).eval()
    x = torch.randn(6, 50, 2)
    inputs = {"b1": x[:1], "batch": x[:4], **({"large": x} if reference else {})}
    bcfg = {"repeats": 1, "warmup": 0, "split_repeats": 1, "batch": 4, "large_batch": 6 if reference else None,
            "reference_int8": reference}
    entry = bench.bench_model(lambda shape: net, lambda shape: net, ["gear"], {"gear": x}, inputs, bcfg,
                              compile_it=False)
    assert ("int8_eager" in entry) is reference and ("int8_speedup_eager" in entry) is reference
    assert ("windows_per_s_large_batch" in entry["fp32_eager"]) is reference
    assert entry["fp32_eager"]["windows_per_s"] > 0 and entry["fastest_fp32"] == "fp32_eager"
    assert set(entry["test_split_s"]["gear"]) == {"fp32_eager", "windows"}


def test_float_modules_stay_float_and_unknown_names_are_refused(trained_mlp):
    clf, X, y = trained_mlp
    settings = TrainSettings(lr=3e-4, epochs=2, batch_size=32, seed=2)
    result = qat.train_qat(clf.network_, X, y, settings, X, y, freeze_last=1, float_modules=("prepare", "net.0"))
    ops = qat.op_precision(result.model)
    assert ops["float"] == {"linear": 1} and ops["int8"]["linear"] == 4  # the first of five layers stays float
    with pytest.raises(ValueError, match="has no module 'net.9'"):
        qat.train_qat(clf.network_, X, y, settings, X, y, freeze_last=1, float_modules=("net.9",))


def test_every_configured_float_module_exists_in_its_model():
    from pathlib import Path

    from toolpath.models.registry import build
    from toolpath.pipeline import config, settings

    cfg = config.compose_config(Path(__file__).resolve().parents[1], [])
    float_modules = cfg.qat.float_modules
    assert set(float_modules) == set(cfg.qat.models)  # each quantized model says what stays float
    for name in cfg.qat.models:
        known = {m for m, _ in build(settings.training(cfg, cfg.shapes[0], name)[0]).named_modules()}
        assert set(float_modules[name]) <= known, name


@pytest.mark.parametrize("name", ["convmixer", "cnn", "mcrl"])
def test_conv1d_as_conv2d_is_the_same_function(name):
    from toolpath import models

    torch.manual_seed(0)
    net = {"convmixer": lambda: models.ConvMixer1d(dim=16, depth=2), "cnn": models.CNN, "mcrl": MCRL}[name]().eval()
    x = torch.randn(16, 50, 2).cumsum(1)
    as2d = qat.conv1d_as_conv2d(net).eval()
    assert not any(isinstance(m, torch.nn.Conv1d) for m in as2d.modules())
    assert any(isinstance(m, torch.nn.Conv1d) for m in net.modules())  # the original is left as it was
    with torch.inference_mode():
        torch.testing.assert_close(as2d(x), net(x), rtol=1e-5, atol=1e-5)


def test_conv1d_as_conv2d_keeps_the_float_modules_one_dimensional():
    """A convolution QAT leaves in float stays 1-D (the 2-D form only costs a layout reorder), and the
    FP32 twin the benchmark times is the network in the INT8 graph's form: the same function."""
    from toolpath import models

    torch.manual_seed(0)
    net = models.CNN().eval()
    kept = qat.conv1d_as_conv2d(net, keep=["prepare", "conv"])
    assert isinstance(kept.conv, torch.nn.Conv1d)
    mixer = models.ConvMixer1d(dim=16, depth=2).eval()
    twin = qat.fp32_twin(mixer, ["prepare", "embed.0"], quantize_conv1d=True)
    assert isinstance(twin.embed[0], torch.nn.Conv1d) and isinstance(twin.depthwise[0][0], qat.Conv1dAs2d)
    assert qat.fp32_twin(mixer, ["embed.0"], quantize_conv1d=False) is mixer
    x = torch.randn(8, 50, 2).cumsum(1)
    with torch.inference_mode():
        torch.testing.assert_close(twin(x), mixer(x), rtol=1e-5, atol=1e-5)


def test_quantize_conv1d_gives_the_convolutions_int8():
    from toolpath.models import ConvMixer1d

    torch.manual_seed(0)
    X, y = easy_split(32)
    net = ConvMixer1d(dim=8, depth=1).eval()
    result = qat.train_qat(net, X, y, TrainSettings(lr=1e-4, epochs=2, batch_size=32), X[:8], y[:8], freeze_last=1,
                           quantize_conv1d=True)
    ops = qat.op_precision(result.model)
    convolutions = sum(isinstance(m, torch.nn.Conv1d) for m in net.modules())  # embed, depthwise, pointwise
    assert ops["int8"].get("conv2d", 0) == convolutions > 0  # every one, as a 2-D INT8 convolution
    assert "conv1d" not in ops["float"] and "conv2d" not in ops["float"]


def test_quantize_outputs_fake_quantizes_what_a_convolution_feeds_a_float_op():
    """ONNX Runtime fuses DQ -> Conv -> Q into one integer kernel only with the Q: each convolution
    followed by GELU gets an output fake quantizer with ``quantize_outputs``, none without."""
    from toolpath.models import ConvMixer1d

    torch.manual_seed(0)
    net = ConvMixer1d(dim=8, depth=1).eval()
    example = torch.as_tensor(easy_split(4)[0][:2])

    def users_of_convolutions(outputs):
        prepared = qat.prepare(net, example, ("prepare",), quantize_conv1d=True, quantize_outputs=outputs)
        return [[u.op for u in node.users] for node in prepared.graph.nodes if "conv2d" in str(node.target)]

    assert users_of_convolutions(False) == [["call_function"]] * 3  # straight into GELU
    assert users_of_convolutions(True) == [["call_module"]] * 3  # into its fake quantizer, then GELU


def test_reduce_range_quantizes_activations_on_seven_bits(trained_mlp):
    clf, X, _ = trained_mlp
    example = torch.as_tensor(X[:2])
    ranges = {}
    for reduce in (False, True):
        prepared = qat.prepare(clf.network_, example, reduce_range=reduce)
        # activation fake-quantizers are unsigned (quant_min 0); weights are signed, per channel
        ranges[reduce] = {m.quant_max for m in prepared.modules() if getattr(m, "quant_min", None) == 0}
    assert ranges == {False: {255}, True: {127}}


def test_train_and_eval_swap_dropout_only_in_a_graph_that_has_it():
    """A prepared graph with dropout (the CNN) gets torchao's swap: random in training, deterministic in
    evaluation; one without (the MLP) keeps its ops as they are and only flips the mode flag."""
    from toolpath import models

    torch.manual_seed(0)
    x = torch.randn(8, 50, 2).cumsum(1)
    cnn = qat.prepare(models.CNN(dropout=0.5).eval(), x[:2], ("prepare", "conv"))
    cnn(x)  # the observers see data, then hold their scales: only dropout can change an output
    qat.freeze_observers(cnn)
    cnn.train()
    assert not torch.equal(cnn(x), cnn(x))  # dropout on
    cnn.eval()
    assert torch.equal(cnn(x), cnn(x))
    mlp = qat.prepare(models.MLP().eval(), x[:2], ("prepare", "net.0"))
    mlp(x)
    qat.freeze_observers(mlp)
    ops = [str(node.target) for node in mlp.graph.nodes]
    assert not any(op in target for target in ops for op in qat.MODE_DEPENDENT_OPS)
    mlp.train()
    trained = mlp(x)
    mlp.eval()
    assert [str(node.target) for node in mlp.graph.nodes] == ops and torch.equal(mlp(x), trained)
