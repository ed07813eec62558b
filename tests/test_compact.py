"""MCRL's compact ONNX form (toolpath.inference.compact): the same function as the network, in <= 150 nodes."""

import numpy as np
import onnx
import pytest
import torch
import yaml
from onnx import TensorProto, helper

from conftest import REPO
from toolpath.inference import compact
from toolpath.inference.qat import conv1d_as_conv2d
from toolpath.inference.recurrences import graph_nodes
from toolpath.inference.runtimes import RUNTIMES, runner
from toolpath.models import registry
from toolpath.models.mcrl import MCRL


def _turning_terms(windows: np.ndarray) -> np.ndarray:
    """The compact graph's turning terms alone, run in ONNX Runtime: (B, 2, n - 2), channel by channel."""
    import onnxruntime as ort

    g = compact._Graph()
    terms, _ = compact._turning(g, "windows")
    graph = helper.make_graph(g.nodes, "turning", [helper.make_tensor_value_info("windows", TensorProto.FLOAT,
                                                                                 ["b", windows.shape[1], 2])],
                              [helper.make_tensor_value_info(terms, TensorProto.FLOAT, None)], g.initializers)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 18)])
    out = ort.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"]).run(None, {
        "windows": windows.astype(np.float32)})[0]
    return out.reshape(len(windows), 2, -1)


def test_turning_terms_of_a_square_corner_a_straight_line_and_a_repeated_point():
    """Eq. 1-3 by hand: a 90-degree left turn is cos 0, sin 1, so (cos - 1, sin) = (-1, 1); a straight line
    turns nowhere; a point written twice has a segment of no length (no turn, not NaN)."""
    corner = np.array([[i, 0] for i in range(25)] + [[24, i] for i in range(1, 26)], dtype=float)
    line = np.stack([np.linspace(0, 10, 50), np.linspace(0, 5, 50)], axis=1)
    repeated = line.copy()
    repeated[30] = repeated[29]
    terms = _turning_terms(np.stack([corner, line, repeated]))
    expected = np.zeros((2, 48))
    expected[:, 23] = (-1, 1)  # inner point 24, the corner, is the 24th of the 48 inner points
    np.testing.assert_allclose(terms[0], expected, atol=1e-6)
    np.testing.assert_allclose(terms[1], 0, atol=1e-6)
    assert np.isfinite(terms[2]).all()
    np.testing.assert_allclose(terms[2], 0, atol=1e-5)  # the turns at both ends of the empty segment count as none


def _mcrl(**overrides) -> MCRL:
    config = yaml.safe_load((REPO / "conf/model/mcrl_fused.yaml").read_text())
    config.pop("schedule")
    torch.manual_seed(3)
    net = registry.build({**config, **overrides}).eval()
    net.prepare.scale.copy_(torch.tensor([30.0, 7.0]))  # as fitted on training windows: not 1
    return net


def _windows(count: int = 64) -> torch.Tensor:
    torch.manual_seed(4)
    windows = (torch.randn(count, 50, 2) * 0.05 + torch.tensor([0.4, 0.1])).cumsum(1)
    windows[1, 20] = windows[1, 19]  # a zero-length segment
    windows[2] = torch.stack([torch.linspace(0, 5, 50), torch.zeros(50)], dim=1)  # a straight line
    return windows


@pytest.mark.parametrize("fuse,resample,as_2d", [("output", "area", False), ("hidden", "linear", False),
                                                 ("output", "area", True)])
def test_compact_form_is_the_network_in_both_runtimes(tmp_path, fuse, resample, as_2d):
    net = _mcrl(fuse=fuse, resample=resample)
    twin = conv1d_as_conv2d(net).eval() if as_2d else net  # the benchmark's FP32 twin: its Conv1d as a Conv2d
    windows = _windows()
    with torch.inference_mode():
        expected = net(windows).numpy()
    compact.save_compact(twin, tmp_path / "compact.onnx")
    onnx.checker.check_model(str(tmp_path / "compact.onnx"))
    for runtime in RUNTIMES:
        logits = runner(tmp_path / "compact.onnx", runtime, 1)(windows.numpy())
        np.testing.assert_allclose(logits, expected, rtol=1e-4, atol=1e-5)
    # and not a function that ignores what it is given: another network's weights give other logits
    compact.save_compact(_mcrl(fuse=fuse, resample=resample, dropout=0.1).apply(
        lambda m: torch.nn.init.normal_(m.weight) if isinstance(m, torch.nn.Linear) else None), tmp_path / "other.onnx")
    assert not np.allclose(runner(tmp_path / "other.onnx", "onnxruntime", 1)(windows.numpy()), expected, atol=1e-3)


def test_compact_form_of_the_pipelines_mcrl_has_at_most_150_nodes_counting_its_loops(tmp_path):
    compact.save_compact(_mcrl(), tmp_path / "compact.onnx")
    nodes = graph_nodes(tmp_path / "compact.onnx")
    assert nodes["nodes"] + nodes["loop_body_nodes"] <= 150, nodes
    assert nodes["recurrent_nodes"] == 4  # one Scan loop (the three tanh RNNs) and three LSTM nodes
    graph = onnx.load(str(tmp_path / "compact.onnx")).graph
    assert sorted(n.op_type for n in graph.node if n.op_type in ("Scan", "LSTM", "RNN")) == ["LSTM"] * 3 + ["Scan"]


def test_compact_form_is_written_for_mcrl_on_the_turning_terms_only():
    assert compact.supported(_mcrl()) and not compact.supported(_mcrl(inputs="coordinates"))
    with pytest.raises(ValueError, match="turning terms only"):
        compact.compact_mcrl(_mcrl(inputs="coordinates"))
