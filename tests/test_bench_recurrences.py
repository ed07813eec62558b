"""The RNN layer benchmark (toolpath.bench.recurrences): its lean form is the torch layer's function (the
native form's is checked in test_recurrences; the timings themselves run in `make bench` only)."""

import pytest
import torch
from torch import nn

pytest.importorskip("onnxruntime", reason="the `runtimes` extra of pyproject.toml is not installed")

from toolpath.bench import recurrences  # noqa: E402


def test_lean_layer_is_the_torch_rnn():
    torch.manual_seed(3)
    rnn = nn.RNN(3, 5, batch_first=True).eval()
    x = torch.randn(4, 7, 3)
    with torch.no_grad():
        expected = rnn(x)[0]
        # the first step by hand: h_1 = tanh(W x_1 + b_ih + b_hh), h_0 = 0
        first = torch.tanh(x[:, 0] @ rnn.weight_ih_l0.T + rnn.bias_ih_l0 + rnn.bias_hh_l0)
        lean = recurrences._LeanLayer(rnn)(x)
    assert torch.allclose(lean[:, 0], first, atol=1e-6)
    assert torch.allclose(lean, expected, atol=1e-6)

