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
