"""Benchmarks (never timed tests).  Run: python -m toolpath.bench [--threads N] [--repeats N]

Writes ``reports/bench/models.json``: per model, the parameter count and the FP32 eager forward
time for a batch of 256 windows (median of interleaved repetitions after warm-up, torch threads
fixed), beside the exact rule's time on the same batch.  Prints the table.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import torch
from rich.console import Console
from rich.table import Table

from toolpath import config
from toolpath.models.__main__ import parameter_count
from toolpath.models.registry import MODEL_NAMES, build
from toolpath.stages._common import write_json

OUT = Path("reports/bench")


def machine() -> dict:
    return {"python": platform.python_version(), "torch": torch.__version__, "cpu": platform.processor() or
            platform.machine(), "cores": os.cpu_count(),
            "threads": torch.get_num_threads()}


def bench_models(threads: int, repeats: int, batch: int = 256, seed: int = 0) -> dict:
    """Median FP32 forward time per ``batch`` windows for every model (seconds and windows/s)."""
    torch.set_num_threads(threads)
    cfg = config.load().models
    x = torch.randn(batch, 50, 2, generator=torch.Generator().manual_seed(seed)).cumsum(dim=1)
    x_np = x.double().numpy()
    runners = {}
    for name in MODEL_NAMES:
        model = build(cfg[name])
        if name == "rule":
            model.fit(x_np)
            runners[name] = (model, lambda m=model: m.predict(x_np))
        else:
            model.eval()
            runners[name] = (model, lambda m=model: m(x))
    times: dict[str, list[float]] = {name: [] for name in runners}
    with torch.no_grad():
        for _, run in runners.values():
            for _ in range(3):
                run()  # warm-up
        for _ in range(repeats):  # interleaved: drift on the machine hits every model alike
            for name, (_, run) in runners.items():
                start = time.perf_counter()
                run()
                times[name].append(time.perf_counter() - start)
    result = {}
    for name, (model, _) in runners.items():
        median = statistics.median(times[name])
        result[name] = {"parameters": parameter_count(model), "fp32_forward_s_per_batch": median,
                        "windows_per_s": batch / median, "batch": batch}
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--threads", type=int, default=2, help="torch intra-op threads")
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args(argv)
    models = bench_models(args.threads, args.repeats)
    write_json({"machine": machine(), "models": models}, OUT / "models.json")
    table = Table(title=f"FP32 forward, batch 256, {args.threads} threads (median of {args.repeats})")
    for column in ("model", "parameters", "ms / 256 windows", "windows / s"):
        table.add_column(column, justify="right")
    for name, row in models.items():
        table.add_row(name, f"{row['parameters']:,}", f"{row['fp32_forward_s_per_batch'] * 1e3:.2f}",
                      f"{row['windows_per_s']:,.0f}")
    Console().print(table)
    print(f"wrote {OUT / 'models.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
