"""Quantization-aware training to INT8 through PT2E (torch.export + torchao), Sec. 5.1.2 "Inference Time".

Route (``../shared/platform-notes.md``): ``torch.export`` with a dynamic batch dimension ->
``prepare_qat_pt2e`` with the x86 inductor quantizer (QAT config: per-channel INT8 weights, per-tensor
INT8 activations with fake quantization; the modules of ``qat.float_modules``, the input normalisation
and the layers that see the raw turning terms, stay float; ``qat.quantize_outputs`` models also get
their convolution and linear outputs quantized) -> train with the same loop and schedule as FP32 -> observers
frozen for the last epoch(s), so the final epochs fine-tune against fixed scales -> ``convert_pt2e``.
The converted graph is exported again and saved as ``.pt2``; it reloads to identical outputs.

Run eagerly, the converted graph is a *reference* INT8 graph: every quantized Linear / Conv1d is a
dequantize -> float op -> quantize sequence that simulates INT8 arithmetic exactly; real INT8 kernels
come from compiling it with inductor (``torch._inductor.config.freezing = True``), which the benchmark
does.  :func:`op_precision` lists which compute ops are INT8 and which stay float (RNN, LSTM,
normalisers, the attention's products), per model, for the report.
"""

from __future__ import annotations

import os
import time
import types
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch import nn

from toolpath.inference.lean import lean_form
from toolpath.models.rule import CLASSES as CATEGORIES
from toolpath.models.training.classifier import from_checkpoint
from toolpath.models.training.loop import EpochRecord, TrainSettings, fit_network, predict_logits
from toolpath.models.training.metrics import classification_metrics
from toolpath.models.training.progress import EpochBar

# compute ops we classify; the rest (reshapes, activations, pooling, quant/dequant) carry no weights
COMPUTE_OPS = ("linear", "conv1d", "conv2d", "matmul", "bmm", "mm", "addmm", "einsum", "rnn_tanh", "lstm",
               "layer_norm", "group_norm", "batch_norm")


RELOAD_CHECK = 512  # test windows the reloaded .pt2 must reproduce bit for bit


def _dynamic_batch(max_batch: int = 1 << 16) -> tuple[dict, ...]:
    return ({0: torch.export.Dim("batch", min=1, max=max_batch)},)


def export(net: nn.Module, example: torch.Tensor) -> torch.export.ExportedProgram:
    """``torch.export`` with a dynamic batch dimension (the example needs a batch of at least 2)."""
    return torch.export.export(net, (example,), dynamic_shapes=_dynamic_batch())


class Conv1dAs2d(nn.Module):
    """A ``Conv1d`` computed as a ``Conv2d`` of height 1: the same weights and the same function.  The
    x86 quantizer annotates 2-D convolutions only, so this is how a 1-D convolution gets INT8 weights
    (per channel) and, in ONNX Runtime and OpenVINO, INT8 kernels."""

    def __init__(self, conv: nn.Conv1d) -> None:
        super().__init__()
        padding = _explicit_padding(conv)
        if padding is None:
            raise ValueError(f"{conv}: 'same' padding with an even kernel span has no symmetric Conv2d form")
        self.conv = nn.Conv2d(conv.in_channels, conv.out_channels, (1, conv.kernel_size[0]),
                              stride=(1, conv.stride[0]), padding=padding, dilation=(1, conv.dilation[0]),
                              groups=conv.groups, bias=conv.bias is not None, padding_mode=conv.padding_mode)
        with torch.no_grad():
            self.conv.weight.copy_(conv.weight.unsqueeze(2))
            if conv.bias is not None:
                self.conv.bias.copy_(conv.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.conv(x.unsqueeze(2)).squeeze(2)


def _explicit_padding(conv: nn.Conv1d) -> tuple[int, int] | None:
    """The Conv2d padding of ``conv`` as numbers (the quantizer matches the plain conv2d op only, not
    its 'same' overload); None where 'same' would pad unevenly."""
    if conv.padding == "valid":
        return (0, 0)
    if conv.padding == "same":
        span = conv.dilation[0] * (conv.kernel_size[0] - 1)
        return None if span % 2 or conv.stride[0] != 1 else (0, span // 2)
    return (0, conv.padding[0])


def conv1d_as_conv2d(net: nn.Module, keep: Sequence[str] = ()) -> nn.Module:
    """A copy of ``net`` with every ``Conv1d`` replaced by its :class:`Conv1dAs2d` (module names kept),
    except those in or under the modules named in ``keep`` (the float modules: in float the 2-D form only
    costs ONNX Runtime a layout reorder), and one whose 'same' padding would be uneven (stays float)."""
    import copy

    net = copy.deepcopy(net)
    kept = tuple(keep)
    for prefix, module in list(net.named_modules()):
        for name, child in list(module.named_children()):
            full = f"{prefix}.{name}" if prefix else name
            if any(full == k or full.startswith(f"{k}.") for k in kept):
                continue
            if isinstance(child, nn.Conv1d) and _explicit_padding(child) is not None:
                setattr(module, name, Conv1dAs2d(child))
    return net


def fp32_twin(net: nn.Module, float_modules: Sequence[str] = (), quantize_conv1d: bool = False) -> nn.Module:
    """``net`` in the graph form :func:`prepare` gives its INT8 graph (its lean form,
    :func:`toolpath.inference.lean.lean_form`; with ``quantize_conv1d``, every 1-D convolution outside
    ``float_modules`` computed as 2-D): the same function, so that FP32 and INT8 are
    timed as the same graph differing only in precision.  ONNX Runtime runs a grouped 1-D convolution by a
    generic path 4-5x slower than the 2-D one: against the 1-D FP32 file ConvMixer's INT8 file looked 2.8x
    faster, against this twin it is not faster at all."""
    net = lean_form(net)
    return conv1d_as_conv2d(net, keep=float_modules).eval() if quantize_conv1d else net.eval()


MATRIX_OPS = ("aten.conv2d.default", "aten.linear.default")


def _quantize_outputs(model: torch.fx.GraphModule) -> None:
    """Give every annotated Conv2d / Linear whose output the quantizer left float an output fake
    quantizer too (the spec of its input activation), unless the op after it is quantized already.
    An ONNX Runtime QDQ graph fuses DQ -> Conv -> Q into one QLinearConv (DQ -> MatMul -> Q likewise)
    only with the Q after it; without, the op runs in float."""
    for node in model.graph.nodes:
        note = node.meta.get("quantization_annotation")
        if node.op != "call_function" or str(node.target) not in MATRIX_OPS or note is None or \
                note.output_qspec is not None or not note.input_qspec_map:
            continue
        if any(getattr(user.meta.get("quantization_annotation"), "_annotated", False) for user in node.users):
            continue
        spec = note.input_qspec_map.get(node.args[0])
        if spec is not None:
            note.output_qspec = spec


def prepare(net: nn.Module, example: torch.Tensor, float_modules: Sequence[str] = (),
            quantize_conv1d: bool = False, reduce_range: bool = False,
            quantize_outputs: bool = False) -> torch.fx.GraphModule:
    """Export ``net`` and insert fake-quantize observers for QAT with the x86 inductor quantizer,
    leaving the modules named in ``float_modules`` (``named_modules()`` names) in float;
    ``quantize_conv1d``: 1-D convolutions too (:class:`Conv1dAs2d`), else they stay float;
    ``reduce_range``: activations on 7 bits (0-127), so that x86 CPUs without VNNI, whose u8 x s8
    kernels (VPMADDUBSW) add pairs of products in saturating 16-bit lanes, compute them exactly;
    ``quantize_outputs``: also the outputs of convolutions and linears that feed a float op
    (:func:`_quantize_outputs`), which ONNX Runtime then runs as integer kernels."""
    from torchao.quantization.pt2e.quantize_pt2e import prepare_qat_pt2e
    from torchao.quantization.pt2e.quantizer.x86_inductor_quantizer import (
        X86InductorQuantizer,
        get_default_x86_inductor_quantization_config,
    )

    net = lean_form(net.eval())  # the graph form the ONNX runtimes run fastest (toolpath.inference.lean)
    if quantize_conv1d:
        net = conv1d_as_conv2d(net, keep=float_modules).eval()
    class Quantizer(X86InductorQuantizer):
        def annotate(self, model: torch.fx.GraphModule) -> torch.fx.GraphModule:
            model = super().annotate(model)
            if quantize_outputs:
                _quantize_outputs(model)
            return model

    quantizer = Quantizer().set_global(
        get_default_x86_inductor_quantization_config(is_qat=True, reduce_range=reduce_range))
    known = {name for name, _ in net.named_modules()}
    for name in float_modules:
        if name not in known:
            raise ValueError(f"qat.float_modules: {type(net).__name__} has no module {name!r}")
        quantizer.set_module_name_qconfig(name, None)
    from toolpath.inference.conv_bn_kinds import present_kinds_only
    from toolpath.inference.pattern_graphs import pattern_graphs_kept

    with present_kinds_only(), pattern_graphs_kept():
        prepared = prepare_qat_pt2e(export(net, example).module(), quantizer)
    # .train() / .eval() on an exported graph swap dropout / batch-norm ops, so the FP32 training loop runs
    # on it unchanged
    return allow_train_eval(prepared)


# aten ops whose behaviour differs between training and inference (the ops torchao's swaps rewrite)
MODE_DEPENDENT_OPS = ("dropout", "batch_norm")


def allow_train_eval(model: torch.fx.GraphModule) -> torch.fx.GraphModule:
    """``model.train()`` / ``model.eval()`` on an exported graph: torchao's supported swap of its dropout and
    batch-norm ops, or, for a graph with neither, the mode flag alone.  The swap rewrites only those ops, so
    on a graph without them it changes nothing, yet each call exports its patterns, twice per QAT epoch (to
    validation and back): on a graph with them, each pattern is exported once per process
    (:mod:`toolpath.inference.pattern_graphs`)."""
    from torchao.quantization.pt2e import allow_exported_model_train_eval
    from torchao.quantization.pt2e.export_utils import _EXPORTED_TRAINING_ATTR

    from toolpath.inference.pattern_graphs import pattern_graphs_kept

    if any(node.op == "call_function" and any(op in str(node.target) for op in MODE_DEPENDENT_OPS)
           for node in model.graph.nodes):
        swap = allow_exported_model_train_eval(model).train

        def train(self: torch.fx.GraphModule, mode: bool = True) -> torch.fx.GraphModule:
            with pattern_graphs_kept():  # the swap's patterns exported once, not at every call
                swap(mode)
            return self
    else:
        def train(self: torch.fx.GraphModule, mode: bool = True) -> torch.fx.GraphModule:
            setattr(self, _EXPORTED_TRAINING_ATTR, mode)
            return self

    model.train = types.MethodType(train, model)  # type: ignore[method-assign]
    model.eval = types.MethodType(lambda self: train(self, False), model)  # type: ignore[method-assign]
    return model


def freeze_observers(prepared: torch.fx.GraphModule) -> None:
    """Stop updating quantization scales and zero points (fake quantization stays on)."""
    from torchao.quantization.pt2e import disable_observer

    prepared.apply(disable_observer)


def convert(prepared: torch.fx.GraphModule) -> torch.fx.GraphModule:
    from torchao.quantization.pt2e.quantize_pt2e import convert_pt2e

    from toolpath.inference.conv_bn_kinds import present_kinds_only
    from toolpath.inference.pattern_graphs import pattern_graphs_kept

    prepared.eval()
    with present_kinds_only(), pattern_graphs_kept():
        converted = convert_pt2e(prepared)
    return allow_train_eval(_drop_unused(converted))


def _drop_unused(model: torch.fx.GraphModule) -> torch.fx.GraphModule:
    """Remove the FP32 weights the converted graph no longer reads (it reads their INT8 copies), so
    the saved ``.pt2`` does not carry both."""
    model.graph.eliminate_dead_code()
    model.recompile()
    used = {node.target for node in model.graph.nodes if node.op == "get_attr"}
    for name in [n for n, _ in (*model.named_parameters(), *model.named_buffers())]:
        if name not in used:
            owner, _, attr = name.rpartition(".")
            delattr(model.get_submodule(owner) if owner else model, attr)
    return model


@dataclass
class QATResult:
    model: torch.fx.GraphModule
    history: list[EpochRecord] = field(default_factory=list)


def train_qat(net: nn.Module, X: np.ndarray, y: np.ndarray, settings: TrainSettings, X_val: np.ndarray,
              y_val: np.ndarray, freeze_last: int = 1, on_epoch: Callable[[EpochRecord], None] | None = None,
              float_modules: Sequence[str] = (), quantize_conv1d: bool = False,
              reduce_range: bool = False, quantize_outputs: bool = False) -> QATResult:
    """QAT of ``net`` (its current weights are the start) on class indices ``y``; returns the converted model.

    ``settings`` is the FP32 schedule (learning rate, batch) with the QAT epoch count, run as a
    fine-tune on Table 2's staircase (about constant over QAT's few steps): no warm-up, no clipping,
    no early stopping or best-state restore (a restored state would mix observer states).
    Observers freeze after epoch ``epochs - freeze_last``; ``float_modules`` stay unquantized, and
    1-D convolutions too unless ``quantize_conv1d``.
    """
    if not 0 <= freeze_last < settings.epochs:
        raise ValueError("QAT needs 0 <= freeze_last < epochs: observers must see data before they freeze")
    example = torch.as_tensor(X[:2], dtype=torch.float32)
    prepared = prepare(net, example, float_modules, quantize_conv1d, reduce_range, quantize_outputs)

    def hook(record: EpochRecord) -> None:
        if record.epoch == settings.epochs - freeze_last:
            freeze_observers(prepared)
        if on_epoch is not None:
            on_epoch(record)

    fixed = TrainSettings(**{**settings.__dict__, "patience": None, "aux_loss_weight": 0.0, "schedule": "step",
                             "clip_grad_norm": None, "restore_best": False, "normalise_inputs": False})
    history = fit_network(prepared, X, y, fixed, X_val, y_val, on_epoch=hook)
    return QATResult(convert(prepared), history)


def save(model: torch.fx.GraphModule, example: torch.Tensor, path: Path) -> int:
    """Export the converted graph and save it as ``.pt2`` (the same bytes for the same model and
    example); returns the file size in bytes."""
    path.parent.mkdir(parents=True, exist_ok=True)
    program = export(model, example)
    # the provenance metadata holds Python object ids (graph_id) and the stack traces absolute source
    # paths, which differ run to run and checkout to checkout; without them the archive (and its
    # content-derived serialization id) is the same bytes from the same seed, wherever it runs
    for graph_module in program.graph_module.modules():
        if isinstance(graph_module, torch.fx.GraphModule):
            for node in graph_module.graph.nodes:
                node.meta.pop("from_node", None)
                node.meta.pop("stack_trace", None)
    torch.export.save(program, str(path))
    return os.path.getsize(path)


def load(path: Path) -> nn.Module:
    """A saved INT8 model, callable on (B, 50, 2) float32 windows.

    Raises
    ------
    FileNotFoundError, ValueError
        When the file is missing or is not a ``.pt2`` (zip) archive; torch.export's own errors otherwise.
    """
    import logging
    import zipfile

    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: INT8 model not found; run `dvc repro qat` first")
    if not zipfile.is_zipfile(path):  # torch.export.load would log a traceback before failing
        raise ValueError("not a .pt2 (zip) archive")
    # torchao reports its optional CUDA kernels missing at import: noise on a CPU machine
    logging.getLogger("torchao").setLevel(logging.ERROR)
    import torchao.quantization.pt2e  # noqa: F401  (registers the quantize / dequantize ops the file uses)

    return allow_train_eval(torch.export.load(str(path)).module())


def tensor_bytes(model: nn.Module) -> dict[str, int]:
    """Bytes of the model's tensors (parameters, buffers, frozen constants) by dtype: what the weights
    occupy, apart from the fixed overhead of a ``.pt2`` archive (serialised graph and metadata)."""
    tensors = {id(t): t for t in (*model.parameters(), *model.buffers())}
    for value in vars(model).values():
        if isinstance(value, torch.Tensor):
            tensors[id(value)] = value
    out: dict[str, int] = {}
    for t in tensors.values():
        key = str(t.dtype).replace("torch.", "")
        out[key] = out.get(key, 0) + t.numel() * t.element_size()
    return dict(sorted(out.items()))


def op_precision(model: torch.fx.GraphModule) -> dict[str, dict[str, int]]:
    """Count the converted graph's compute ops by precision: ``int8`` when an input comes straight
    from a dequantize node (the reference pattern of a quantized op), else ``float``."""
    counts: dict[str, Counter] = {"int8": Counter(), "float": Counter()}
    for node in model.graph.nodes:
        if node.op != "call_function":
            continue
        name = str(node.target).split(".")[-2] if "." in str(node.target) else str(node.target)
        if name not in COMPUTE_OPS:
            continue
        from_dequant = any(getattr(a, "op", None) == "call_function" and "dequantize" in str(a.target)
                           for a in node.args[:2] if isinstance(a, torch.fx.Node))
        counts["int8" if from_dequant else "float"][name] += 1
    return {k: dict(sorted(v.items())) for k, v in counts.items()}


def quantize_one(name: str, checkpoint: dict, parts: dict, settings: TrainSettings, freeze_last: int,
                 out: Path, show_epochs: bool = True, float_modules: Sequence[str] = (),
                 quantize_conv1d: bool = False, reduce_range: bool = False,
                 quantize_outputs: bool = False) -> tuple[dict, float, np.ndarray]:
    """QAT from a trained FP32 checkpoint, convert, save to ``out``, reload-check and score one model on
    ``parts`` (windows and class indices 0-3 per split); returns (its record, seconds of QAT, the saved
    graph's prediction per test window: what :func:`ship_int8` compares the runtimes with)."""
    clf = from_checkpoint(checkpoint)
    started = time.perf_counter()
    if show_epochs:
        with EpochBar(f"qat {name}", settings.epochs) as bar:
            result = train_qat(clf.network_, *parts["train"], settings, *parts["val"], freeze_last=freeze_last,
                               on_epoch=bar.update, float_modules=float_modules, quantize_conv1d=quantize_conv1d,
                               reduce_range=reduce_range, quantize_outputs=quantize_outputs)
    else:
        result = train_qat(clf.network_, *parts["train"], settings, *parts["val"], freeze_last=freeze_last,
                           float_modules=float_modules, quantize_conv1d=quantize_conv1d, reduce_range=reduce_range,
                           quantize_outputs=quantize_outputs)
    seconds = time.perf_counter() - started
    X_test = torch.as_tensor(parts["test"][0])
    logits = predict_logits(result.model, X_test)
    size = save(result.model, X_test[:2], out)
    reloaded = predict_logits(load(out), X_test[:RELOAD_CHECK])  # the saved graph, on a slice: same bytes out
    proba = torch.softmax(logits, dim=1).numpy()
    metrics = classification_metrics(CATEGORIES[parts["test"][1]], proba)
    return {"status": "ok", "test": metrics,
            "reload_identical": bool(torch.equal(logits[:RELOAD_CHECK], reloaded)),
            "file_bytes": size, "tensor_bytes": tensor_bytes(result.model),
            "fp32_tensor_bytes": tensor_bytes(from_checkpoint(checkpoint).network_),
            "ops": op_precision(result.model), "epochs": len(result.history),
            "float_modules": list(float_modules), "quantize_conv1d": quantize_conv1d,
            "reduce_range": reduce_range, "quantize_outputs": quantize_outputs}, seconds, proba.argmax(1)


def ship_int8(checkpoint: dict, out: Path, onnx: Path, test: tuple[np.ndarray, np.ndarray], predicted: np.ndarray,
              threads: int = 1) -> dict:
    """The INT8 graph saved at ``out`` exported to ``onnx`` and scored in every runtime of
    :mod:`toolpath.inference.runtimes` (on ``threads`` threads) on the ``test`` split (windows, class
    indices 0-3), against the FP32 network's accuracy and the saved graph's ``predicted`` classes.  Apart
    from :func:`quantize_one` so that a worker can ship one shape while another trains the next."""
    from toolpath.inference import runtimes

    X_test = torch.as_tensor(test[0])
    fp32_predictions = predict_logits(from_checkpoint(checkpoint).network_.eval(), X_test).argmax(1).numpy()
    fp32_accuracy = float((fp32_predictions == test[1]).mean())
    return {"onnx_file_bytes": runtimes.export_int8(out, X_test[:2], onnx),
            "runtimes": runtimes.score(onnx, *test, predicted, fp32_accuracy, threads,
                                       lambda y, p: classification_metrics(CATEGORIES[y], p))}
