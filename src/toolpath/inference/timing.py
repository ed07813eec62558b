"""Inference timing for Table 4: latency, throughput and whole-split time, measured honestly.

Protocol: torch threads fixed, warm-up calls first, then repetitions *interleaved* across every
variant (so drift on the machine hits all alike), each variant's turn opening with an untimed call
(:func:`timed` says why), the median reported.  Variants per model: FP32
eager, FP32 compiled (inductor), INT8 eager (the converted reference graph: dequantize -> float op ->
quantize, which simulates INT8 exactly but runs no INT8 kernel) and INT8 compiled (inductor with
freezing: real INT8 kernels).  :func:`branch_profile` splits an MCRL forward pass by branch.
"""

from __future__ import annotations

import os
import platform
import statistics
import time
from collections.abc import Callable
from contextlib import nullcontext
from pathlib import Path

import numpy as np
import torch
from torch import nn

Runner = Callable[[torch.Tensor], object]


def compiled(model: nn.Module) -> nn.Module:
    """``torch.compile`` with inductor's weight freezing (needed for the INT8 fusions); dynamic batch."""
    import torch._inductor.config as inductor_config

    inductor_config.freezing = True
    return torch.compile(model, dynamic=True)


def timed(runners: dict[str, Runner], inputs: dict[str, torch.Tensor], repeats: int, warmup: int = 2,
          progress: Callable[[], None] | None = None, warm: torch.Tensor | None = None,
          settle: float = 0.05) -> dict[str, dict[str, float]]:
    """Median seconds of every runner on every input, with warm-up and interleaved repetitions
    (``warm``: one extra warm-up call per runner on this input, e.g. a slice of a large one).

    Each runner's turn in a repetition opens with a pause of ``settle`` seconds and an untimed call (on
    ``warm``, else the first input): after a call, torch's OpenMP and ONNX Runtime's worker threads
    spin on for milliseconds, and on 2 cores that slowed whichever runner came next (OpenVINO's FP32
    ConvNeXt: 28 ms alone, 46-54 ms right after ONNX Runtime; ONNX Runtime's FP32 CNN 2.5 ms alone,
    7.6 ms after torch even behind one untimed call), which made one variant look slow and the next
    fast.  The pause outlasts the spinning; the call warms the runner's own caches."""
    first = next(iter(inputs.values()), None)
    with torch.inference_mode():
        for run in runners.values():
            if warm is not None:
                run(warm)
            for x in inputs.values():
                for _ in range(warmup):
                    run(x)
        samples: dict[tuple[str, str], list[float]] = {(r, i): [] for r in runners for i in inputs}
        for _ in range(repeats):
            for r, run in runners.items():
                time.sleep(settle)  # the previous runner's threads stop spinning
                run(warm if warm is not None else first)
                for i, x in inputs.items():
                    start = time.perf_counter()
                    run(x)
                    samples[(r, i)].append(time.perf_counter() - start)
            if progress is not None:
                progress()
    out: dict[str, dict[str, float]] = {}
    for (r, i), values in samples.items():
        out.setdefault(r, {})[i] = statistics.median(values)
    return out


# MCRL's parts, in the order of its forward pass (module attribute names of toolpath.models.MCRL)
MCRL_GROUPS = {"input (normalise)": ("prepare",), "attention branches (linear, resample, attention)": ("branches",),
               "MLP": ("mlp",), "CNN": ("conv", "pool", "cnn_fc", "dropout"), "RNN": ("rnns",),
               "LSTM": ("lstms",), "heads and fusion": ("heads", "fusion")}


def branch_profile(model: nn.Module, x: torch.Tensor, repeats: int = 20) -> dict[str, float]:
    """Median seconds per MCRL part over ``repeats`` forward passes (forward hooks on each part's
    modules), plus ``total`` and ``unattributed`` (concatenations, interpolation outside modules)."""
    spent: dict[str, float] = {}
    starts: dict[int, float] = {}
    handles = []

    def attach(module: nn.Module, group: str) -> None:
        def pre(mod, _args):
            starts[id(mod)] = time.perf_counter()

        def post(mod, _args, _out):
            spent[group] = spent.get(group, 0.0) + time.perf_counter() - starts.pop(id(mod))

        handles.append(module.register_forward_pre_hook(pre))
        handles.append(module.register_forward_hook(post))

    for group, names in MCRL_GROUPS.items():
        for name in names:
            part = getattr(model, name)
            for module in (part if isinstance(part, nn.ModuleList) else [part]):
                attach(module, group)
    runs: dict[str, list[float]] = {g: [] for g in [*MCRL_GROUPS, "total"]}
    try:
        with torch.inference_mode():
            model(x)  # warm-up
            for _ in range(repeats):
                spent.clear()
                start = time.perf_counter()
                model(x)
                runs["total"].append(time.perf_counter() - start)
                for g in MCRL_GROUPS:
                    runs[g].append(spent.get(g, 0.0))
    finally:
        for h in handles:
            h.remove()
    result = {g: statistics.median(v) for g, v in runs.items()}
    result["unattributed"] = max(result["total"] - sum(result[g] for g in MCRL_GROUPS), 0.0)
    return result


def threads(count: int):
    """Context in which torch uses ``count`` intra-op threads (restored afterwards)."""
    previous = torch.get_num_threads()

    class _Threads:
        def __enter__(self):
            torch.set_num_threads(count)

        def __exit__(self, *exc):
            torch.set_num_threads(previous)

    return _Threads() if count else nullcontext()


def machine(thread_count: int) -> dict:
    """What the figures were measured on."""
    return {"python": platform.python_version(), "torch": torch.__version__, "machine": platform.machine(),
            "cpu": cpu_name(), "cores": os.cpu_count(), "torch_threads": thread_count,
            "int8_dot_product": int8_dot_product()}


def int8_dot_product(flags: set[str] | None = None) -> str:
    """The x86 instruction that multiplies INT8 here, from the CPU flags: VNNI's ``vpdpbusd`` does 4x
    the multiply-adds of an FP32 FMA per instruction; without it (AVX2) u8 x s8 products go through
    ``vpmaddubsw`` + ``vpmaddwd`` + ``vpaddd``, little more than FP32's rate, so INT8 gains come mostly
    from moving 4x fewer weight bytes."""
    if flags is None:
        try:
            flags = {f for line in Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("flags")
                     for f in line.split(":", 1)[1].split()}
        except OSError:
            return "unknown"
    for flag, name in (("amx_int8", "AMX-INT8"), ("avx512_vnni", "AVX512-VNNI"), ("avx_vnni", "AVX-VNNI")):
        if flag in flags:
            return name
    return "none (AVX2: vpmaddubsw)" if "avx2" in flags else "none"


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def rates(seconds: dict[str, float], batch: int, large: int | None) -> dict[str, float]:
    out = {"latency_b1_ms": 1e3 * seconds["b1"], "s_per_batch": seconds["batch"],
           "windows_per_s": batch / seconds["batch"]}
    if large and "large" in seconds:
        out["windows_per_s_large_batch"] = large / seconds["large"]
    return out


def onnx_runners(files: dict[str, Path], threads: int, runtimes: tuple[str, ...] | None = None) -> dict[str, Runner]:
    """``{"<runtime>_<precision>": runner}`` for the ONNX files ``{"fp32": path, "int8": path}`` in every
    runtime of :mod:`toolpath.inference.runtimes` (or those of ``runtimes``; torch tensors in, like the
    torch variants)."""
    from toolpath.inference import runtimes as known

    def on_tensors(run: known.Runner) -> Runner:
        return lambda x: run(x.numpy())

    return {f"{runtime}_{precision}": on_tensors(known.runner(path, runtime, threads))
            for runtime in (runtimes or known.RUNTIMES) for precision, path in files.items() if path.is_file()}


def bench_model(fp32: Callable[[str], nn.Module], int8: Callable[[str], nn.Module | None], shapes: list[str],
                tests: dict, inputs: dict, bcfg: dict, compile_it: bool,
                onnx: Callable[..., dict[str, Runner]] | None = None,
                choose: Callable[[dict], dict] | None = None) -> dict:
    """Table 4's figures of one model.  ``fp32(shape)`` / ``int8(shape)`` give its networks (int8 None
    when there is no INT8 model; its eager reference graph is timed unless ``bcfg["reference_int8"]`` is
    false), ``onnx(shape, runtimes=None)`` its ONNX runtime variants (:func:`onnx_runners`).
    Latency and throughput of every variant on the first shape's files; INT8 speed-ups per runtime and
    against the fastest FP32; ``choose(entry)`` names the shipped runtime (:func:`shipped`).  Then each
    shape's whole test split with its own weights: FP32 eager, and the shipped runtime's FP32 and INT8
    (the eager INT8 reference graph, slow by construction, is timed on batches only)."""
    runners = {"fp32_eager": fp32(shapes[0])}
    quantized = int8(shapes[0])
    if quantized is not None and bcfg["reference_int8"]:
        runners["int8_eager"] = quantized
    if compile_it:
        runners["fp32_compiled"] = compiled(runners["fp32_eager"])
        if quantized is not None:
            runners["int8_compiled"] = compiled(quantized)
    if onnx is not None:
        runners.update(onnx(shapes[0]))
    # a turn opens with a whole batch: long enough for the previous runtime's threads to stop spinning
    seconds = timed(runners, inputs, bcfg["repeats"], bcfg["warmup"], warm=inputs["batch"])
    entry: dict = {v: rates(s, bcfg["batch"], bcfg["large_batch"]) for v, s in seconds.items()}
    for mode in ("eager", "compiled", "onnxruntime", "openvino"):
        fp32_key, int8_key = (f"fp32_{mode}", f"int8_{mode}") if mode in ("eager", "compiled") else \
            (f"{mode}_fp32", f"{mode}_int8")
        if int8_key in entry and fp32_key in entry:
            entry[f"int8_speedup_{mode}"] = entry[fp32_key]["s_per_batch"] / entry[int8_key]["s_per_batch"]
    fastest_fp32 = min((entry[v]["s_per_batch"], v) for v in entry if "fp32" in v)
    entry["fastest_fp32"] = fastest_fp32[1]
    for v in [v for v in entry if "int8" in v and isinstance(entry[v], dict)]:
        entry[v]["speedup_vs_fastest_fp32"] = fastest_fp32[0] / entry[v]["s_per_batch"]
    if choose is not None:
        entry["shipped"] = choose(entry)
    best = (entry.get("shipped") or {}).get("runtime")
    split: dict = {}
    for shape in shapes:  # each shape's own weights
        variants = {"fp32_eager": fp32(shape)}
        if best is not None and onnx is not None:
            variants.update(onnx(shape, runtimes=(best,)))  # only the shipped runtime's sessions
        # one timed pass after a warm-up on a slice: a 5,000-window split takes seconds, not microseconds
        split[shape] = {v: s["test"] for v, s in timed(variants, {"test": tests[shape]}, bcfg["split_repeats"],
                                                        0, warm=tests[shape][:bcfg["batch"]]).items()}
        split[shape]["windows"] = len(tests[shape])
    entry["test_split_s"] = split
    return entry


def bench_rule(rule, shapes: list[str], tests: dict, inputs: dict, bcfg: dict) -> dict:
    """The exact rule's figures, the floor of Table 4."""
    def run(x: torch.Tensor) -> np.ndarray:
        return rule.predict(x.numpy())

    seconds = timed({"rule": run}, inputs, bcfg["repeats"], bcfg["warmup"])["rule"]
    entry = rates(seconds, bcfg["batch"], bcfg["large_batch"])
    entry["test_split_s"] = {s: timed({"rule": run}, {"test": tests[s]}, bcfg["split_repeats"], 0,
                                      warm=tests[s][:bcfg["batch"]])["rule"]["test"] for s in shapes}
    return entry


def shipped(entry: dict, qat_entries: dict[str, dict], max_drop_points: float) -> dict:
    """The INT8 runtime to ship for one model: the fastest INT8 ONNX variant of ``entry`` at the
    throughput batch among the runtimes whose INT8 file lost at most ``max_drop_points`` of test
    accuracy against the FP32 network on every shape (``qat_entries``: the qat stage's record of
    the model per shape).  With none eligible, ``runtime`` is None and ``why`` says so."""
    from toolpath.inference.runtimes import RUNTIMES

    drops = {r: [q.get("runtimes", {}).get(r, {}).get("accuracy_drop_points") for q in qat_entries.values()]
             for r in RUNTIMES}
    eligible = [r for r in RUNTIMES if f"{r}_int8" in entry and drops[r] and
                all(d is not None and d <= max_drop_points for d in drops[r])]
    if not eligible:
        return {"runtime": None, "why": f"no runtime keeps every shape's INT8 accuracy within {max_drop_points} "
                                        f"points of FP32: {drops}"}
    best = max(eligible, key=lambda r: entry[f"{r}_int8"]["windows_per_s"])
    return {"runtime": best, "accuracy_drop_points": dict(zip(qat_entries, drops[best], strict=True)),
            "speedup_same_runtime": entry.get(f"int8_speedup_{best}"),
            "speedup_vs_fastest_fp32": entry[f"{best}_int8"]["speedup_vs_fastest_fp32"]}
