"""torchao's pattern graphs, exported once per process.

torchao rewrites a QAT graph by matching small pattern functions (conv + batch-norm in its fused and folded
forms, dropout and batch-norm in training and inference form) and exports each pattern with
``torch.export`` every time it needs it: at prepare and convert, and twice per QAT epoch for a graph with
dropout or batch-norm (``.train()`` / ``.eval()`` swap those ops), about 0.1-0.5 s a pattern.  A pattern's
graph depends only on the function's code, the values it closes over, the shapes and types of its example
inputs and its keyword arguments, so within :func:`pattern_graphs_kept` it is exported once per such key
and each caller gets a copy of its own (the rewrite copies a replacement's nodes into the model).  A pattern
whose key cannot be read (a value that is neither a tensor nor a plain constant) is exported as before.
"""

from __future__ import annotations

import copy
import importlib
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import torch

# the modules that call torchao's exporter of patterns (qat_utils imported it by name)
_CALLERS = ("torchao.quantization.pt2e.utils", "torchao.quantization.pt2e.qat_utils")
_NAME = "_get_aten_graph_module_for_pattern"
_KEPT: dict[tuple, torch.fx.GraphModule] = {}


def _part(value: Any) -> Any:
    """What of ``value`` a pattern's exported graph depends on (a tensor: its shape, type and device)."""
    if isinstance(value, torch.Tensor):
        return "tensor", tuple(value.shape), value.dtype, value.device.type
    if value is None or isinstance(value, bool | int | float | str) or callable(value):
        return value
    raise TypeError(type(value).__name__)


def pattern_key(pattern: Any, example_inputs: tuple, is_cuda: bool, kwargs: dict) -> tuple | None:
    """The key a pattern's graph is kept under, or None when it cannot be read."""
    function = getattr(pattern, "fn", pattern)  # torchao's WrapperModule holds the function it exports
    code = getattr(function, "__code__", None)
    if code is None:
        return None
    try:
        cells = tuple(_part(cell.cell_contents) for cell in function.__closure__ or ())
        inputs = tuple(_part(value) for value in example_inputs)
        keywords = tuple((name, _part(value)) for name, value in sorted(kwargs.items()))
        key = (code, cells, inputs, bool(is_cuda), keywords)
        hash(key)
    except (TypeError, ValueError):  # an unreadable or unhashable value: no key
        return None
    return key


@contextmanager
def pattern_graphs_kept() -> Iterator[None]:
    """Within the block, torchao exports each pattern graph once per process and key; each call gets a copy.
    With a torchao that keeps its exporter of patterns elsewhere, torchao runs as it is."""
    callers = []
    for name in _CALLERS:
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        if hasattr(module, _NAME):
            callers.append((module, getattr(module, _NAME)))
    if not callers:
        yield
        return
    export = callers[0][1]

    def kept(pattern, example_inputs, is_cuda=False, **kwargs):
        key = pattern_key(pattern, example_inputs, is_cuda, kwargs)
        if key is None:
            return export(pattern, example_inputs, is_cuda, **kwargs)
        if key not in _KEPT:
            _KEPT[key] = export(pattern, example_inputs, is_cuda, **kwargs)
        with warnings.catch_warnings():  # torch's copy of a graph's tree specs notes its own deprecated check
            warnings.simplefilter("ignore", FutureWarning)
            return copy.deepcopy(_KEPT[key])

    for module, _ in callers:
        setattr(module, _NAME, kept)
    try:
        yield
    finally:
        for module, original in callers:
            setattr(module, _NAME, original)
