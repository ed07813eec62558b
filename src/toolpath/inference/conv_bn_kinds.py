"""torchao's conv + batch-norm rewrites, asked only about the convolution kinds a graph holds.

``prepare_qat_pt2e`` fuses each conv + batch-norm into its QAT form, and ``convert_pt2e`` folds it back into
the convolution; both try the patterns of every kind, 1-D and 2-D convolutions and transposed ones, and
export each pattern graph (the fold has many per kind) whether or not the graph holds that kind.  A kind
the graph does not hold cannot match, so skipping it changes nothing (the tests compare the graphs' code
and outputs); a graph that holds a kind, or a generic ``aten.convolution`` that could be any, is rewritten
by torchao as before.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import torch
import torch.nn.functional as F

_ATEN = torch.ops.aten
_KIND = {F.conv1d: _ATEN.conv1d, F.conv2d: _ATEN.conv2d,
         F.conv_transpose1d: _ATEN.conv_transpose1d, F.conv_transpose2d: _ATEN.conv_transpose2d}
_ANY_KIND = {_ATEN.convolution, _ATEN._convolution}


def holds(graph_module: torch.fx.GraphModule, conv_fn) -> bool:
    """Whether ``graph_module`` may hold a convolution of ``conv_fn``'s kind (True for a kind not known here)."""
    present = {getattr(node.target, "overloadpacket", None) for node in graph_module.graph.nodes
               if node.op == "call_function"}
    kind = _KIND.get(conv_fn)
    return kind is None or kind in present or bool(present & _ANY_KIND)


_HELPERS = ("_fuse_conv_bn_qat_helper", "_fold_conv_bn_qat_helper")  # one kind's rewrite, in prepare and convert


@contextmanager
def present_kinds_only() -> Iterator[None]:
    """Within the block, torchao's conv + batch-norm fusing and folding skip the convolution kinds a graph
    does not hold (torchao's own rewrite where this torchao release keeps its helpers elsewhere)."""
    from torchao.quantization.pt2e import qat_utils

    originals = {name: getattr(qat_utils, name) for name in _HELPERS if hasattr(qat_utils, name)}

    def only_if_held(helper):
        return lambda m, conv_fn, *args, **kwargs: helper(m, conv_fn, *args, **kwargs) if holds(m, conv_fn) else m

    for name, helper in originals.items():
        setattr(qat_utils, name, only_if_held(helper))
    try:
        yield
    finally:
        for name, helper in originals.items():
            setattr(qat_utils, name, helper)
