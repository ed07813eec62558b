"""Inference benchmark for Table 4: FP32 and INT8, eager and compiled, beside the exact rule.

Run: python -m toolpath.stages.benchmark   (also ``make bench``)

Per model: latency at batch 1, throughput at ``benchmark.batch`` (and ``large_batch``), the time to
classify each shape's whole test split, and the model file sizes; FP32 eager and INT8 eager (the
reference graph) for every model, FP32 and INT8 compiled with inductor for ``benchmark.compile``
(30-65 s of compilation per graph here).  Timings use the gear models (the architectures, hence the
speed, are the same for every shape); the test-split times load each shape's own models.  Plus a
per-branch profile of MCRL.  Writes ``<paths.metrics>/inference.json`` (DVC metrics; timings vary
between runs by nature) and logs it to MLflow.  A benchmark, never a test.
"""

from __future__ import annotations

import os
import platform
from pathlib import Path

import numpy as np
import torch
from omegaconf import OmegaConf

from toolpath import config, tracking
from toolpath.reports.paper import TABLE4
from toolpath.stages._common import load_checkpoint, load_windows, progress, write_json
from toolpath.training import qat
from toolpath.training.bench import branch_profile, compiled, threads, timed
from toolpath.training.classifier import from_checkpoint


def machine(thread_count: int) -> dict:
    return {"python": platform.python_version(), "torch": torch.__version__, "machine": platform.machine(),
            "cpu": _cpu_name(), "cores": os.cpu_count(), "torch_threads": thread_count}


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def _fp32(models_dir: Path, shape: str, name: str) -> torch.nn.Module:
    return from_checkpoint(load_checkpoint(models_dir / shape / f"{name}.pt")).network_.eval()


def _int8(models_dir: Path, shape: str, name: str) -> torch.nn.Module | None:
    path = models_dir / "int8" / shape / f"{name}.pt2"
    if not path.is_file():
        return None
    model = qat.load(path)
    model.eval()  # the exported-graph eval() switches dropout in place and returns None
    return model


def _rates(seconds: dict[str, float], batch: int, large: int) -> dict[str, float]:
    return {"latency_b1_ms": 1e3 * seconds["b1"], "s_per_batch": seconds["batch"],
            "windows_per_s": batch / seconds["batch"], "windows_per_s_large_batch": large / seconds["large"]}


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    bcfg = OmegaConf.to_container(cfg.benchmark, resolve=True)
    models_dir = Path(cfg.paths.models)
    shapes = list(cfg.shapes)
    tests = {s: torch.as_tensor(load_windows(Path(cfg.paths.windows) / f"{s}.npz")["windows"][
        load_windows(Path(cfg.paths.windows) / f"{s}.npz")["split"] == 2]) for s in shapes}
    gen = torch.Generator().manual_seed(config.seed_for(cfg.seed, "benchmark"))
    pool = tests[shapes[0]]
    pick = torch.randint(0, len(pool), (bcfg["large_batch"],), generator=gen)
    inputs = {"b1": pool[pick[:1]], "batch": pool[pick[: bcfg["batch"]]], "large": pool[pick]}
    torch.use_deterministic_algorithms(False)  # inference only; allow the fastest kernels
    result: dict = {"setup": {**machine(bcfg["threads"]), **{k: bcfg[k] for k in ("repeats", "warmup", "batch",
                                                                                  "large_batch")},
                              "timing_shape": shapes[0], "compiled": bcfg["compile"]},
                    "models": {}, "paper_table4_s": TABLE4}
    with tracking.stage_run("benchmark", config.flat(bcfg, "benchmark")), threads(bcfg["threads"]):
        import mlflow

        for name in progress(list(bcfg["models"]), "benchmark"):
            result["models"][name] = _bench_model(name, models_dir, shapes, tests, inputs, bcfg)
        result["rule"] = _bench_rule(models_dir, shapes, tests, inputs, bcfg)
        mcrl = _fp32(models_dir, shapes[0], "mcrl") if "mcrl" in bcfg["models"] else None
        if mcrl is not None:
            result["mcrl_branch_profile_ms"] = {k: 1e3 * v for k, v in
                                                branch_profile(mcrl, inputs["batch"], bcfg["repeats"]).items()}
        out = Path(cfg.paths.metrics) / "inference.json"
        write_json(result, out)
        mlflow.log_metrics({k: v for k, v in config.flat(result["models"]).items() if isinstance(v, int | float)})
        mlflow.log_artifact(str(out))


def _bench_model(name: str, models_dir: Path, shapes: list[str], tests: dict, inputs: dict, bcfg: dict) -> dict:
    fp32, int8 = _fp32(models_dir, shapes[0], name), _int8(models_dir, shapes[0], name)
    runners = {"fp32_eager": fp32}
    if int8 is not None:
        runners["int8_eager"] = int8
    if name in bcfg["compile"]:
        runners["fp32_compiled"] = compiled(fp32)
        if int8 is not None:
            runners["int8_compiled"] = compiled(int8)
    seconds = timed(runners, inputs, bcfg["repeats"], bcfg["warmup"])
    entry: dict = {v: _rates(s, bcfg["batch"], bcfg["large_batch"]) for v, s in seconds.items()}
    entry["fp32_file_bytes"] = (models_dir / shapes[0] / f"{name}.pt").stat().st_size
    int8_path = models_dir / "int8" / shapes[0] / f"{name}.pt2"
    entry["int8_file_bytes"] = int8_path.stat().st_size if int8_path.is_file() else None
    if int8 is None:
        entry["int8_missing"] = f"{int8_path} not found (see reports/metrics/qat/{shapes[0]}.json)"
    split: dict = {}
    for shape in shapes:  # each shape's own weights, eager
        variants = {"fp32_eager": _fp32(models_dir, shape, name)}
        quantized = _int8(models_dir, shape, name)
        if quantized is not None:
            variants["int8_eager"] = quantized
        split[shape] = {v: s["test"] for v, s in timed(variants, {"test": tests[shape]}, max(3, bcfg["repeats"] // 3),
                                                        1).items()}
        split[shape]["windows"] = len(tests[shape])
    entry["test_split_s"] = split
    for mode in ("eager", "compiled"):
        if f"int8_{mode}" in entry and f"fp32_{mode}" in entry:
            entry[f"int8_speedup_{mode}"] = entry[f"fp32_{mode}"]["s_per_batch"] / entry[f"int8_{mode}"]["s_per_batch"]
    return entry


def _bench_rule(models_dir: Path, shapes: list[str], tests: dict, inputs: dict, bcfg: dict) -> dict:
    rule = from_checkpoint(load_checkpoint(models_dir / shapes[0] / "rule.pt"))

    def run(x: torch.Tensor) -> np.ndarray:
        return rule.predict(x.numpy())

    seconds = timed({"rule": run}, inputs, bcfg["repeats"], bcfg["warmup"])["rule"]
    entry = _rates(seconds, bcfg["batch"], bcfg["large_batch"])
    entry["test_split_s"] = {s: timed({"rule": run}, {"test": tests[s]}, 3, 1)["rule"]["test"] for s in shapes}
    return entry


if __name__ == "__main__":
    main()
