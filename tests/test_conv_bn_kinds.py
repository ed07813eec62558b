"""torchao's conv + batch-norm rewrites asked only about the convolution kinds a graph holds
(toolpath.inference.conv_bn_kinds): the kinds skipped are exactly those that cannot match."""

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from toolpath.inference import conv_bn_kinds, qat
from toolpath.models import ConvMixer1d

KINDS = (F.conv1d, F.conv2d, F.conv_transpose1d, F.conv_transpose2d)


def traced(*ops) -> torch.fx.GraphModule:
    """A graph calling each aten op in ``ops`` (arguments do not matter to the kinds it holds)."""
    graph = torch.fx.Graph()
    x = graph.placeholder("x")
    for op in ops:
        x = graph.call_function(op, (x,))
    graph.output(x)
    return torch.fx.GraphModule(torch.nn.Module(), graph)


def test_a_graph_holds_the_kinds_of_its_own_convolutions_only():
    aten = torch.ops.aten
    assert [conv_bn_kinds.holds(traced(aten.conv2d.default, aten.relu.default), fn) for fn in KINDS] == \
        [False, True, False, False]
    assert [conv_bn_kinds.holds(traced(aten.conv1d.padding), fn) for fn in KINDS] == [True, False, False, False]
    assert all(conv_bn_kinds.holds(traced(aten.convolution.default), fn) for fn in KINDS)  # could be any kind
    assert conv_bn_kinds.holds(traced(aten.relu.default), F.linear)  # a kind it does not know: asked, never skipped


@pytest.fixture(scope="module")
def as_2d():
    """A prepared ConvMixer, its 1-D convolutions as Conv1dAs2d (aten.conv2d) before batch norms, its
    observers fed one batch, then frozen (a forward pass changes nothing)."""
    torch.manual_seed(0)
    X = np.random.default_rng(0).normal(size=(16, 50, 2)).astype(np.float32)
    prepared = qat.prepare(ConvMixer1d(dim=8, depth=1).eval(), torch.as_tensor(X[:2]), (), quantize_conv1d=True)
    prepared.train()
    prepared(torch.as_tensor(X))
    prepared.eval()
    qat.freeze_observers(prepared)
    return prepared


@pytest.mark.parametrize("helper, example", [  # torchao's own 1-D example inputs of each rewrite
    ("_fold_conv_bn_qat_helper", (torch.randn(1, 1, 3), torch.randn(1, 1, 1), *(torch.randn(1) for _ in range(4)))),
    ("_fuse_conv_bn_qat_helper", (torch.randn(1, 1, 3), torch.randn(1, 1, 1), *(torch.randn(1) for _ in range(5)))),
])
def test_torchaos_rewrite_of_a_kind_the_graph_lacks_changes_nothing_and_is_skipped(as_2d, helper, example):
    from torchao.quantization.pt2e import qat_utils

    x = torch.randn(4, 50, 2)
    code, expected = as_2d.code, as_2d(x)
    rewritten = getattr(qat_utils, helper)(as_2d, F.conv_transpose1d, example, is_cuda=False)
    assert rewritten.code == code and torch.equal(rewritten(x), expected)  # what skipping it saves is a no-op
    called = []
    original = getattr(qat_utils, helper)
    setattr(qat_utils, helper, lambda m, conv_fn, *a, **k: called.append(conv_fn) or m)
    try:
        with conv_bn_kinds.present_kinds_only():
            for fn in KINDS:
                getattr(qat_utils, helper)(as_2d, fn, example, is_cuda=False)
    finally:
        setattr(qat_utils, helper, original)
    assert called == [F.conv2d]
