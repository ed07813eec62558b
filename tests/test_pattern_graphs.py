"""torchao's pattern graphs exported once per process: the same QAT graphs, fewer exports."""

import contextlib

import torch
import torch.nn.functional as F

from conftest import easy_split
from toolpath.inference import pattern_graphs, qat
from toolpath.models.training.loop import TrainSettings


def _patterns(flag):
    def pattern(x):
        return F.dropout(x, p=0.5, training=flag)
    return pattern


def test_a_patterns_key_is_its_code_closure_and_input_shapes_never_tensor_values():
    key = pattern_graphs.pattern_key
    one = torch.randn(1)
    assert key(_patterns(True), (one,), False, {}) == key(_patterns(True), (torch.zeros(1),), False, {})
    assert key(_patterns(True), (one,), False, {}) != key(_patterns(False), (one,), False, {})
    assert key(_patterns(True), (one,), False, {}) != key(_patterns(True), (torch.randn(2),), False, {})
    assert key(_patterns(True), (one,), False, {"scale": 0.5}) != key(_patterns(True), (one,), False, {"scale": 0.25})
    assert key(_patterns(True), (one,), False, {"table": {"a": 1}}) is None  # unreadable: exported as before


def test_qat_gives_the_same_graph_and_logits_with_patterns_kept(monkeypatch):
    """A CNN, whose dropout is swapped twice an epoch (conv + batch-norm patterns go through the same key:
    tests/test_qat.py and tests/test_conv_bn_kinds.py check those graphs)."""
    from torchao.quantization.pt2e import qat_utils, utils

    from toolpath.models import CNN

    X, y = easy_split(32)
    exports, export = [], utils._get_aten_graph_module_for_pattern

    def counted(*args, **kwargs):
        exports.append(1)
        return export(*args, **kwargs)

    for home in (utils, qat_utils):
        monkeypatch.setattr(home, "_get_aten_graph_module_for_pattern", counted)
    results = {}
    for kept in (False, True):
        with monkeypatch.context() as patch:
            if not kept:
                patch.setattr(pattern_graphs, "pattern_graphs_kept", contextlib.nullcontext)
            patch.setattr(pattern_graphs, "_KEPT", {})
            exports.clear()
            torch.manual_seed(0)
            result = qat.train_qat(CNN(channels=4, hidden=16).eval(), X, y,
                                   TrainSettings(lr=1e-3, epochs=2, batch_size=16, seed=1), X[:8], y[:8])
            with torch.no_grad():
                results[kept] = result.model.code, result.model(torch.as_tensor(X)), len(exports)
    assert results[True][0] == results[False][0]
    assert torch.equal(results[True][1], results[False][1])
    assert 0 < results[True][2] < results[False][2]  # each pattern once


def test_a_torchao_without_the_exporter_of_patterns_runs_as_it_is(monkeypatch):
    import sys

    from torchao.quantization.pt2e import qat_utils, utils

    before = utils._get_aten_graph_module_for_pattern, qat_utils._get_aten_graph_module_for_pattern
    with pattern_graphs.pattern_graphs_kept():  # here, torchao's function is replaced
        assert utils._get_aten_graph_module_for_pattern is not before[0]
    for name in pattern_graphs._CALLERS:  # where neither module can be imported, nothing is replaced
        monkeypatch.setitem(sys.modules, name, None)
    with pattern_graphs.pattern_graphs_kept():
        assert (utils._get_aten_graph_module_for_pattern, qat_utils._get_aten_graph_module_for_pattern) == before
    assert (utils._get_aten_graph_module_for_pattern, qat_utils._get_aten_graph_module_for_pattern) == before
