"""The lean graph form (toolpath.inference.lean): the same function, names and parameters as the network
(its ONNX files, and the step-wise RNN translation: tests/test_recurrences.py)."""

import pytest
import torch

from toolpath.inference.lean import lean_form
from toolpath.models import CNN, MCRL, RNN


@pytest.mark.parametrize("fuse", ["hidden", "output"])
def test_lean_form_is_the_network_with_its_names_and_parameters(fuse):
    torch.manual_seed(2)
    net = MCRL(fuse=fuse).eval()
    x = torch.randn(16, 50, 2).cumsum(1)
    lean = lean_form(net)
    assert lean is not net and [n for n, _ in lean.named_modules()] == [n for n, _ in net.named_modules()]
    assert all(torch.equal(a, b) for a, b in zip(lean.state_dict().values(), net.state_dict().values(),
                                                 strict=True))
    with torch.no_grad():
        torch.testing.assert_close(lean(x), net(x), rtol=1e-5, atol=1e-5)  # sums in another order only


@pytest.mark.parametrize("build", [CNN, RNN])
def test_a_network_without_those_modules_is_returned_as_it_is(build):
    net = build()
    assert lean_form(net) is net


def _quantized_linears(prepared: torch.fx.GraphModule) -> int:
    """Linear ops whose weight passes a fake quantizer (the x86 quantizer annotated them INT8)."""
    return sum(1 for node in prepared.graph.nodes
               if node.op == "call_function" and "linear" in str(node.target)
               and isinstance(node.args[1], torch.fx.Node) and node.args[1].op == "call_module"
               and "activation_post_process" in str(node.args[1].target))


def test_qat_quantizes_the_same_layers_in_the_lean_form(monkeypatch):
    from toolpath.inference import qat

    torch.manual_seed(4)
    # short branches: the same layers, and the export traces 6 steps of the first RNN instead of 20 (8 s less)
    net, x = MCRL(fuse="output", points=(50, 8, 6, 4)).eval(), torch.randn(4, 50, 2).cumsum(1)
    float_modules = ["prepare", *(f"branches.{i}.linear" for i in range(4))]  # as conf/qat/default.yaml
    lean = _quantized_linears(qat.prepare(net, x, float_modules))
    monkeypatch.setattr(qat, "lean_form", lambda network: network)
    assert lean == _quantized_linears(qat.prepare(net, x, float_modules)) > 0
