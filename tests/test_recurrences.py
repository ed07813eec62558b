"""Recurrences exported as ONNX RNN nodes (toolpath.inference.recurrences): a hand-computed RNN, the RNN
baseline and MCRL in both runtimes, against torch."""

import math

import numpy as np
import pytest
import torch
from torch import nn

pytest.importorskip("onnxruntime", reason="the `runtimes` extra of pyproject.toml is not installed")
pytest.importorskip("openvino", reason="the `runtimes` extra of pyproject.toml is not installed")

from toolpath.inference import recurrences  # noqa: E402
from toolpath.inference.runtimes import RUNTIMES, export_onnx, runner  # noqa: E402
from toolpath.models import MCRL, RNN  # noqa: E402


class _OneRNN(nn.Module):
    def __init__(self) -> None:
        super().__init__()
        self.rnn = nn.RNN(1, 1, batch_first=True)

    def forward(self, x):
        return self.rnn(x)[0][:, :, 0]


def _export(net, example, path) -> None:
    export_onnx(net, example, path, translations=recurrences.TRANSLATIONS)


@pytest.mark.parametrize("translations", ["native", "stepwise"])
def test_translated_rnn_matches_a_hand_computed_recurrence(translations, tmp_path):
    net = _OneRNN()
    with torch.no_grad():  # h_t = tanh(x_t + 0.5 h_{t-1} + 0.25 - 0.25)
        net.rnn.weight_ih_l0.fill_(1.0)
        net.rnn.weight_hh_l0.fill_(0.5)
        net.rnn.bias_ih_l0.fill_(0.25)
        net.rnn.bias_hh_l0.fill_(-0.25)
    x = torch.tensor([[[1.0], [0.0], [2.0]], [[0.0], [0.0], [0.0]]])
    table = recurrences.TRANSLATIONS if translations == "native" else recurrences.STEPWISE
    export_onnx(net, x, tmp_path / "one.onnx", translations=table)
    h1 = math.tanh(1.0)
    h2 = math.tanh(0.5 * h1)
    expected = np.array([[h1, h2, math.tanh(2.0 + 0.5 * h2)], [0.0, 0.0, 0.0]])
    nodes = recurrences.graph_nodes(tmp_path / "one.onnx")
    assert nodes["recurrent_nodes"] == (1 if translations == "native" else 0)
    for runtime in RUNTIMES:
        np.testing.assert_allclose(runner(tmp_path / "one.onnx", runtime, 1)(x.numpy()), expected, atol=1e-6)


@pytest.mark.parametrize("name", ["rnn", "mcrl"])
def test_native_form_is_the_network_with_its_recurrences_as_onnx_nodes(name, tmp_path):
    torch.manual_seed(0)
    # MCRL on short branches: the same modules, 4-8 steps per recurrence to trace instead of 10-30
    net = (RNN() if name == "rnn" else MCRL(fuse="output", points=(50, 8, 6, 4))).eval()
    x = torch.randn(16, 50 if name == "mcrl" else 12, 2).cumsum(1)  # the RNN reads any length
    native = recurrences.native_form(net)
    with torch.no_grad():
        expected = net(x).numpy()
        np.testing.assert_allclose(native(x).numpy(), expected, atol=1e-5)
    _export(native, x[:2], tmp_path / "native.onnx")
    nodes = recurrences.graph_nodes(tmp_path / "native.onnx")
    assert nodes["recurrent_nodes"] == (3 if name == "rnn" else 6)  # MCRL: 3 RNN + 3 LSTM layers
    torch.save(net.state_dict(), tmp_path / "net.pt")
    if name == "rnn":  # unrolled, the file is many times the checkpoint
        assert (tmp_path / "native.onnx").stat().st_size <= 2 * (tmp_path / "net.pt").stat().st_size
    for runtime in RUNTIMES:
        np.testing.assert_allclose(runner(tmp_path / "native.onnx", runtime, 1)(x.numpy()), expected,
                                   rtol=1e-4, atol=1e-4)


def test_compare_forms_times_every_form_side_by_side(tmp_path):
    torch.manual_seed(1)
    net = RNN(hidden=(8, 8, 8)).eval()
    x = torch.randn(32, 6, 2).cumsum(1)  # a short sequence: the unrolled export grows with its steps
    export_onnx(net, x[:2], tmp_path / "shipped.onnx")  # the default translation: step by step, lean
    torch.save(net.state_dict(), tmp_path / "net.pt")
    calls = []

    def time_runners(runners):
        calls.append(sorted(runners))
        return {k: 0.01 for k in runners}

    out = recurrences.compare_forms(net, tmp_path / "shipped.onnx", tmp_path, tmp_path / "net.pt",
                                    x, time_runners, lambda path, rt: runner(path, rt, 1))
    forms = ("shipped", "exporter", "native")
    assert calls == [sorted(f"{f}_{rt}" for f in forms for rt in RUNTIMES)]  # one interleaved run
    assert out["native"]["recurrent_nodes"] == 3 and out["shipped"]["recurrent_nodes"] == 0
    assert set(out) == set(forms)  # no ContextRNN, no unhoisted form
    assert out["native"]["nodes"] < out["shipped"]["nodes"] < out["exporter"]["nodes"]
    assert out["native"]["speed_vs_exporter"]["openvino"] == 1
    import onnx  # the shipped file: each recurrent weight once, shared by the steps, and no per-node provenance

    shipped = onnx.load(str(tmp_path / "shipped.onnx"))
    assert len([i for i in shipped.graph.initializer if "weight_hh" in i.name]) == 3
    assert not any(node.metadata_props or node.doc_string for node in shipped.graph.node)
    assert all(out[f][f"{rt}_max_logit_diff"] < 1e-4 for f in forms for rt in RUNTIMES)
