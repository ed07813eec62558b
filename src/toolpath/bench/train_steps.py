"""How close training runs to what this machine can compute: one optimizer step of every learned model,
its floating-point work beside the machine's own matrix-multiply rate (issue 45: is the train stage, the
largest item of ``make repro``, bound by overhead or by arithmetic?).

Per model, at the training batch (Table 3's protocol, ``train.protocol.settings.batch_size``) on 50-point
windows: the FLOPs of one forward and backward pass (``torch.utils.flop_counter``; a model with a fused
recurrent layer, ``nn.RNN`` / ``nn.LSTM`` / ``nn.GRU``, whose kernel the counter has no formula for, is
marked uncounted rather than under-counted), the median seconds of one step (zero the gradients, forward,
cross-entropy, backward, AdamW; no augmentation), the rate that gives, and its share of a 1024 x 1024 FP32
matrix product's rate measured right before it on the same threads (the peak a dense kernel reaches here;
small convolutions and attention on 50-point windows reach less).  Where ``reports/pipeline_time.json``
has the model's train stage, also its seconds and what they would be if all of it ran at that rate (the
stage's share of work that is not a training step, evaluation and export, scaled alike: a low estimate).

Run: ``python -m toolpath.bench --only train`` -> ``reports/bench/train_steps.json``.
"""

from __future__ import annotations

import json
import statistics
import time
from pathlib import Path

import torch
from torch.utils.flop_counter import FlopCounterMode

from toolpath.models.registry import build, is_learned

PEAK_SIZE = 1024  # the matrix product whose rate is the machine's dense peak
WINDOW = 50


def gemm_rate(repeats: int = 10) -> float:
    """FLOP/s of a PEAK_SIZE square FP32 matrix product (the median of ``repeats``, after warm-up: this
    machine's rate drifts by tens of per cent, so each model is set beside a rate measured next to it)."""
    a, b = torch.randn(PEAK_SIZE, PEAK_SIZE), torch.randn(PEAK_SIZE, PEAK_SIZE)
    for _ in range(3):
        a @ b
    return 2.0 * PEAK_SIZE ** 3 / statistics.median(_timed(lambda: a @ b) for _ in range(repeats))


def _timed(work) -> float:
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def step_figures(model: torch.nn.Module, batch: int, repeats: int, seed: int = 0) -> dict:
    """FLOPs (None when a fused recurrent layer hides some) and median seconds of one training step."""
    generator = torch.Generator().manual_seed(seed)
    x = torch.randn(batch, WINDOW, 2, generator=generator).cumsum(dim=1)
    y = torch.randint(0, 4, (batch,), generator=generator)
    model.train()
    optimizer = torch.optim.AdamW(model.parameters(), 1e-3)

    def step():
        optimizer.zero_grad()
        torch.nn.functional.cross_entropy(model(x), y).backward()
        optimizer.step()

    counter = FlopCounterMode(display=False)
    with counter:
        torch.nn.functional.cross_entropy(model(x), y).backward()
    fused = sorted({type(m).__name__ for m in model.modules() if isinstance(m, torch.nn.RNNBase)})
    for _ in range(3):
        step()
    seconds = statistics.median(_timed(step) for _ in range(repeats))
    flops = None if fused else float(counter.get_total_flops())
    return {"step_flops": flops, "uncounted": fused or None, "step_s": seconds,
            "flop_per_s": None if flops is None else flops / seconds}


def measure(models: dict, batch: int, threads: int, repeats: int, stage_seconds: dict | None = None) -> dict:
    """:func:`step_figures` of every learned model of ``models`` (name: model config), each beside the
    matrix-product peak measured here, and where ``stage_seconds`` has ``train@<name>``, the stage's
    seconds at that peak."""
    before = torch.get_num_threads()
    torch.set_num_threads(threads)
    try:
        return _measure(models, batch, threads, repeats, stage_seconds)
    finally:
        torch.set_num_threads(before)  # a caller's own thread count is left as it was


def _measure(models: dict, batch: int, threads: int, repeats: int, stage_seconds: dict | None) -> dict:
    torch.manual_seed(0)
    result = {"threads": threads, "batch": batch, "models": {}}
    for name, config in models.items():
        if not is_learned(config):
            continue
        peak = gemm_rate()  # side by side with this model's steps
        entry = step_figures(build(config), batch, repeats) | {"gemm_flop_per_s": peak}
        entry["share_of_gemm_peak"] = None if entry["flop_per_s"] is None else entry["flop_per_s"] / peak
        stage = (stage_seconds or {}).get(f"train@{name}")
        if stage is not None:
            entry["train_stage_s"] = stage
            entry["train_stage_s_at_gemm_peak"] = (None if entry["share_of_gemm_peak"] is None
                                                   else stage * entry["share_of_gemm_peak"])
        result["models"][name] = entry
    counted = [e for e in result["models"].values() if e.get("train_stage_s_at_gemm_peak") is not None]
    if counted:
        result["counted_train_stages_s"] = sum(e["train_stage_s"] for e in counted)
        result["counted_train_stages_s_at_gemm_peak"] = sum(e["train_stage_s_at_gemm_peak"] for e in counted)
    return result


def stage_seconds(path: Path = Path("reports/pipeline_time.json")) -> dict | None:
    """Seconds per stage of the last measured ``make repro`` (None when it has not run here)."""
    return json.loads(path.read_text())["stages"] if path.is_file() else None
