"""Benchmarks (never timed tests).

Run: python -m toolpath.bench [--only models|optimize|runtimes|gcode|arcs|programs|tube|recurrences|planner|warm|train]
[--threads N]

Writes ``reports/bench/models.json``: per model, the parameter count and the FP32 eager forward
time for a batch of 256 windows (median of interleaved repetitions after warm-up, torch threads
fixed), beside the exact rule's time on the same batch.  Writes ``reports/bench/optimize.json``:
NACOA on one rough 50-point window at the paper's population settings (N = 1000, M0 = 10,
M_min = 2, T = 10; G generations) per fidelity mode and gradient, on one core.  Writes
``reports/bench/runtimes.json``: every model FP32 and INT8 in torch, ONNX Runtime and OpenVINO side by
side (:mod:`toolpath.bench.runtimes`; needs the pipeline's models), with the integer kernel's ceiling
(:mod:`toolpath.bench.kernels`).  Writes ``reports/bench/gcode.json``:
reading a G01-dense program and ``toolpath smooth`` end to end, beside gcodeparser and pygcode
(:mod:`toolpath.bench.gcode`).  Writes ``reports/bench/arcs.json``: ``toolpath smooth --arcs --method none``
beside ArcWelder where it is given (:mod:`toolpath.bench.arcs`).  With ``--only programs --programs DIR``,
writes ``reports/bench/programs.json``: ``toolpath smooth`` on every program under DIR, each changed output
checked by a reader written apart (:mod:`toolpath.bench.programs`).  With ``--only tube`` (about ten minutes a
shape), writes ``reports/bench/tube_limit.json``: how far the tube lets any of our methods go on the optimize
stage's windows (:mod:`toolpath.bench.tube_limit`).  Writes ``reports/bench/recurrences.json``: one tanh RNN
layer as the ONNX ``RNN`` node, as the exporter's unrolled steps and as the fewest-node unrolled form, and
MCRL whole in every form of Table 4d (the compact one included), in both runtimes side by side
(:mod:`toolpath.bench.recurrences`).  With ``--only planner``, writes
``reports/bench/planner_limit.json``: the corner cases under the planner, the planner without its tangential
jerk limit and toppra's bound, at three tangential accelerations (:mod:`toolpath.bench.planner_limit`).
Writes ``reports/bench/warm_start.json``: one small stage started in its own process and handed to the warm
server of ``make repro``, alternately (:mod:`toolpath.bench.warm_start`).  Writes ``reports/bench/train_steps.json``:
a training step of every model, FLOPs beside the GEMM rate (:mod:`toolpath.bench.train_steps`).  Prints the tables.
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch
from rich.console import Console
from rich.table import Table

from toolpath.inference.timing import machine
from toolpath.models.registry import build, is_learned, parameter_count
from toolpath.pipeline import config
from toolpath.pipeline.artifacts import write_json

OUT = Path("reports/bench")


def bench_models(threads: int, repeats: int, batch: int = 256, seed: int = 0) -> dict:
    """Median FP32 forward time per ``batch`` windows for every model (seconds and windows/s)."""
    torch.set_num_threads(threads)
    cfg = config.load().models
    x = torch.randn(batch, 50, 2, generator=torch.Generator().manual_seed(seed)).cumsum(dim=1)
    x_np = x.double().numpy()
    runners = {}
    for name in cfg:
        model = build(cfg[name])
        if not is_learned(cfg[name]):
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


def rough_window(seed: int = 0, n: int = 50) -> np.ndarray:
    """A seeded rough window: a 20 mm arc of radius 30 mm with 0.03 mm noise and one 0.3 mm spike."""
    import numpy as np

    rng = np.random.default_rng(seed)
    angle = np.linspace(0.0, 20.0 / 30.0, n)
    pts = 30.0 * np.column_stack([np.cos(angle), np.sin(angle)])
    pts[1:-1] += rng.normal(scale=0.03, size=(n - 2, 2))
    pts[n // 2] += 0.3
    return pts


def bench_optimize(repeats: int, generations: int, seed: int = 0) -> dict:
    """Median seconds of NACOA on one window at the paper's population settings, per mode and gradient."""
    from toolpath.geometry import fitness
    from toolpath.smoothing import SmoothingProblem
    from toolpath.smoothing.nacoa import NACOA, NACOASettings

    window = rough_window(seed)
    out = {}
    for mode in ("none", "bound"):
        for gradient in ("exact", "central"):
            settings = NACOASettings(population=1000, generations=generations, m0=10, m_min=2, m_max=10,
                                     exchange_every=10, gradient=gradient, perturbation=0.05)
            problem = SmoothingProblem(window, mode=mode, tolerance=0.05)
            runs = [NACOA(settings).solve(problem, seed) for _ in range(repeats)]
            out[f"{mode}/{gradient}"] = {
                "seconds_median": statistics.median(r.seconds for r in runs), "population": 1000,
                "generations": generations, "evaluations": runs[0].evaluations,
                "fitness_before": float(fitness(window)), "fitness_after": runs[0].objective}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--only", choices=("models", "optimize", "runtimes", "gcode", "arcs", "programs", "tube",
                                             "recurrences", "planner", "warm", "train"),
                        help="run one benchmark (default: all)")
    parser.add_argument("--threads", type=int, default=2, help="torch intra-op threads")
    parser.add_argument("--repeats", type=int, default=30)
    parser.add_argument("--generations", type=int, default=100, help="NACOA generations G (paper: unstated)")
    parser.add_argument("--arcwelder", help="ArcWelder's console binary (else $ARCWELDER, $ARCWELDER_SRC)")
    parser.add_argument("--shapes", nargs="+", help="--only tube: these shapes (default: every shape)")
    parser.add_argument("--programs", type=Path, help="--only programs: a folder of other people's G-code")
    parser.add_argument("--units", choices=("mm", "inch"), help="--only programs: for a program that sets none")
    args = parser.parse_args(argv)
    if args.only == "programs":
        if args.programs is None or not args.programs.is_dir():
            parser.error("--only programs needs --programs DIR, a folder of G-code programs")
        return _programs(args.programs, args.units)
    if args.only == "tube":
        return _tube(args.shapes or list(config.load().shapes))
    if args.only == "planner":
        return _planner()
    if args.only in (None, "train"):
        _train_steps(args.threads, max(5, args.repeats // 2))
        if args.only == "train":
            return 0
    if args.only in (None, "warm"):
        _warm_start()
        if args.only == "warm":
            return 0
    if args.only in (None, "recurrences"):
        _recurrences(args.threads, max(5, args.repeats // 3))
        if args.only == "recurrences":
            return 0
    if args.only in (None, "arcs"):
        _arcs(args.arcwelder)
        if args.only == "arcs":
            return 0
    if args.only in (None, "gcode"):
        _gcode()
        if args.only == "gcode":
            return 0
    if args.only in (None, "optimize"):
        # one core, as the target says: numpy's elementwise work is single-threaded; pin BLAS anyway
        with _single_thread():
            nacoa = bench_optimize(max(3, args.repeats // 6), args.generations)
        write_json({"machine": machine(torch.get_num_threads()), "nacoa": nacoa}, OUT / "optimize.json")
        table = Table(title="NACOA, one 50-point window, N = 1000, one core (median)")
        for column in ("mode / gradient", "generations", "evaluations", "seconds", "fitness before -> after"):
            table.add_column(column, justify="right")
        for key, row in nacoa.items():
            table.add_row(key, str(row["generations"]), f"{row['evaluations']:,}", f"{row['seconds_median']:.3f}",
                          f"{row['fitness_before']:.3f} -> {row['fitness_after']:.3f}")
        Console().print(table)
        print(f"wrote {OUT / 'optimize.json'}")
        if args.only == "optimize":
            return 0
    if args.only == "runtimes":
        return _runtimes(args.threads, args.repeats)
    models = bench_models(args.threads, args.repeats)
    write_json({"machine": machine(torch.get_num_threads()), "models": models}, OUT / "models.json")
    table = Table(title=f"FP32 forward, batch 256, {args.threads} threads (median of {args.repeats})")
    for column in ("model", "parameters", "ms / 256 windows", "windows / s"):
        table.add_column(column, justify="right")
    for name, row in models.items():
        table.add_row(name, f"{row['parameters']:,}", f"{row['fp32_forward_s_per_batch'] * 1e3:.2f}",
                      f"{row['windows_per_s']:,.0f}")
    Console().print(table)
    print(f"wrote {OUT / 'models.json'}")
    return _runtimes(args.threads, args.repeats) if args.only is None else 0


def _train_steps(threads: int, repeats: int) -> None:
    from toolpath.bench.train_steps import measure, stage_seconds

    cfg = config.load()
    result = measure(cfg.models, int(cfg.train.protocol.settings.batch_size), threads, repeats, stage_seconds())
    write_json({"machine": machine(threads), **result}, OUT / "train_steps.json")
    for name, row in result["models"].items():
        share = "FLOPs uncounted" if row["share_of_gemm_peak"] is None else f"{row['share_of_gemm_peak']:.0%} of GEMM"
        print(f"{name}: {row['step_s'] * 1e3:.1f} ms a step, {share}")
    print(f"wrote {OUT / 'train_steps.json'}")


def _warm_start() -> None:
    from toolpath.bench.warm_start import bench_warm_start

    result = bench_warm_start(Path.cwd())
    write_json({"machine": machine(torch.get_num_threads()), **result}, OUT / "warm_start.json")
    print(f"{result['stage']}: {result['cold_median_s']:.2f} s in its own process, {result['warm_median_s']:.2f} s "
          f"handed to the warm server ({result['speedup']:.1f}x); MCRL training steps in a forked worker "
          f"{result['training_steps']['forked_vs_spawned']:.3f}x the time in a spawned one; "
          f"wrote {OUT / 'warm_start.json'}")


def _planner() -> int:
    from toolpath.bench.planner_limit import bench_planner_limit

    result = bench_planner_limit()
    write_json(result, OUT / "planner_limit.json")
    table = Table(title="Corner cases (s): the planner as configured / read point by point / point by point without "
                        "the tangential jerk limit / toppra's bound; NURBS + PSO's time saved vs G01 under each (%)")
    for column in ("a_t mm/s^2", "case", "G01", "NURBS + PSO", "PSO saved vs G01 %"):
        table.add_column(column)
    for acceleration, cases in result["by_tangential_acceleration"].items():
        for case, rows in cases.items():
            g01, pso = rows["g01"], rows["nurbs_pso"]
            keys = ("planner", "pointwise", "pointwise_without_jerk_limit", "toppra_bound")
            table.add_row(acceleration, case, " / ".join(f"{g01[k]:.3f}" for k in keys),
                          " / ".join(f"{pso[k]:.3f}" for k in keys),
                          " / ".join(f"{pso['saved_vs_g01_pct'][k]:+.2f}" for k in keys))
    Console().print(table)
    print(f"wrote {OUT / 'planner_limit.json'}")
    return 0


def _tube(shapes: list[str]) -> int:
    from toolpath.bench.tube_limit import bench_tube_limit

    result = bench_tube_limit(shapes)
    write_json({"machine": machine(1), **result}, OUT / "tube_limit.json")
    table = Table(title=f"Tube mode, categories 2-4: the stage's figures beside NACOA at {result['factor']}x the "
                        f"generations, best of {result['seeds']} seeds (reduction %, mean over windows)")
    for column in ("shape", "category", "windows", "NACOA (stage)", "NACOA (stronger)", "dispatch (stage)",
                   "oracle dispatch"):
        table.add_column(column, justify="right")
    for shape, node in result["shapes"].items():
        for category, c in node["per_category"].items():
            if not c["windows"]:
                continue
            table.add_row(shape, category, str(c["windows"]), f"{c['stage_nacoa_pct']:.1f}",
                          f"{c['stronger_nacoa_pct']:.1f}", f"{c['stage_dispatch_pct']:.1f}",
                          f"{c['oracle_dispatch_pct']:.1f}")
    Console().print(table)
    print(f"wrote {OUT / 'tube_limit.json'}")
    return 0


def _runtimes(threads: int, repeats: int) -> int:
    from toolpath.bench import kernels
    from toolpath.bench.runtimes import RUNTIMES, measure
    from toolpath.inference.runtimes import op_kind

    cfg = config.load()
    result = measure(list(cfg.benchmark.models), cfg.shapes[0], threads, repeats)
    result["integer_kernel_ceiling"] = kernels.measure(threads, repeats)
    write_json(result, OUT / "runtimes.json")
    table = Table(title=f"windows / s at batch {result['batch']}, {threads} threads; INT8 speed-up in the same runtime "
                        f"and against the fastest FP32 (median of {repeats})")
    for column in ("model", *[f"{r} {p}" for r in RUNTIMES for p in ("FP32", "INT8")],
                   "best INT8 (drop <= 1 pt) / FP32 same", "best INT8 / fastest FP32",
                   "onnxruntime PTQ INT8 (not QAT): / FP32 same, / fastest FP32"):
        table.add_column(column, justify="right")
    for name, entry in result["models"].items():
        rows = entry["variants"]
        cells = [f"{rows[v]['windows_per_s']:,.0f} ({100 * rows[v]['test_accuracy']:.1f} %)" if v in rows else "-"
                 for v in (f"{r}_{p}" for r in RUNTIMES for p in ("fp32", "int8"))]
        int8 = [r for v, r in rows.items() if v.endswith("_int8") and "speedup_same_runtime" in r
                and r["accuracy_drop_points"] <= 1.0]  # a fast graph that lost its accuracy is no winner
        best = max(int8, key=lambda r: r["windows_per_s"]) if int8 else None
        ptq = rows.get("onnxruntime_ptq")
        table.add_row(name, *cells, f"{best['speedup_same_runtime']:.2f}x" if best else "-",
                      f"{best['speedup_vs_fastest_fp32']:.2f}x" if best else "-",
                      f"{ptq['windows_per_s']:,.0f} ({100 * ptq['test_accuracy']:.1f} %): "
                      f"{ptq['speedup_same_runtime']:.2f}x, {ptq['speedup_vs_fastest_fp32']:.2f}x" if ptq else "-")
    Console().print(table)
    profile = Table(title="ONNX Runtime INT8 graph: share of its time in integer kernels, float <-> int8 conversions "
                          "and float operators (its profiler)")
    for column in ("model", "integer", "convert", "float", "largest float operators"):
        profile.add_column(column, justify="right")
    for name, entry in result["models"].items():
        if found := entry.get("onnxruntime_int8_op_profile"):
            share = found["share_by_kind"]
            floats = [f"{op} {100 * v:.0f} %" for op, v in found["share_by_op"].items()
                      if op != "other" and op_kind(op) == "float"][:3]
            profile.add_row(name, *(f"{100 * share[k]:.0f} %" for k in ("integer", "convert", "float")),
                            ", ".join(floats))
    Console().print(profile)
    ceiling = result["integer_kernel_ceiling"]
    kernel = Table(title="ONNX Runtime, one matrix product: FP32 MatMul against INT8 MatMulInteger (the most INT8 can "
                         f"gain on a model's products here; INT8 dot product: {ceiling['int8_dot_product']})")
    for column in ("M x K x N", "FP32 ms", "INT8 ms", "FP32 / INT8"):
        kernel.add_column(column, justify="right")
    for shape, row in ceiling["shapes"].items():
        kernel.add_row(shape, f"{row['fp32_ms']:.3f}", f"{row['int8_ms']:.3f}", f"{row['fp32_over_int8']:.2f}x")
    Console().print(kernel)
    for name, entry in result["models"].items():
        for variant, reason in entry["errors"].items():
            print(f"{name}: {variant} could not run: {reason}")
    print(f"wrote {OUT / 'runtimes.json'}")
    return 0


def _recurrences(threads: int, repeats: int) -> None:
    from toolpath.bench.recurrences import measure, print_tables

    result = measure(threads, repeats)
    write_json(result, OUT / "recurrences.json")
    print_tables(result)
    print(f"wrote {OUT / 'recurrences.json'}")


def _gcode() -> None:
    from toolpath.bench.gcode import measure

    result = measure()
    write_json(result, OUT / "gcode.json")
    table = Table(title=f"reading a {result['file']['lines']:,}-line G01 program; toolpath smooth end to end")
    for column in ("what", "does", "lines / s", "peak RSS MB"):
        table.add_column(column, justify="right")
    rows = [*result["readers"].items(), *((f"toolpath smooth: {m}", r) for m, r in result["smooth"].items())]
    for name, row in rows:
        table.add_row(name, row.get("does", ""), f"{row['lines_per_s']:,.0f}" if row.get("lines_per_s") else
                      row.get("error", "-"), f"{row['peak_rss_mb']:.0f}" if "peak_rss_mb" in row else "-")
    Console().print(table)
    print(f"wrote {OUT / 'gcode.json'}")


def _arcs(arcwelder: str | None) -> None:
    from toolpath.bench.arcs import measure

    result = measure(arcwelder)
    write_json(result, OUT / "arcs.json")
    table = Table(title=f"--arcs --method none at {result['tolerance_mm']} mm beside ArcWelder "
                        f"({result['arcwelder_flags']}; {result['arcwelder']})")
    for column in ("program", "lines in", "tool", "lines out", "arcs", "largest deviation mm", "seconds", "peak MB"):
        table.add_column(column, justify="right")
    for name, row in result["programs"].items():
        for tool in ("ours", "arcwelder"):
            if run := row.get(tool):
                dev = run.get("deviation_mm", "-")
                table.add_row(name, f"{row['lines_in']:,}", tool, f"{run['lines_out']:,}" if "lines_out" in run
                              else run.get("error", "failed")[:60], str(run.get("arcs", "-")),
                              f"{dev:.4f}" if isinstance(dev, float) else str(dev)[:40], f"{run['seconds']:.2f}",
                              f"{run['peak_rss_mb']:.0f}" if "peak_rss_mb" in run else "-")
    Console().print(table)
    print(f"arcs only: {result['arcs_only_lines_per_s']:,.0f} lines/s on the G01-dense program; "
          f"wrote {OUT / 'arcs.json'}")
    if (large := result.get("large_program")) and "lines_per_s" in large["ours"]:
        print(f"arcs only, {large['lines_in']:,} lines: {large['ours']['lines_per_s']:,.0f} lines/s, "
              f"{large['ours'].get('peak_rss_mb', float('nan')):.0f} MB peak, {large['ours']['lines_out']:,} lines out")


def _programs(folder: Path, units: str | None) -> int:
    from toolpath.bench.programs import measure

    result = measure(folder, units)
    write_json(result, OUT / "programs.json")
    summary = result["summary"]
    table = Table(title=f"toolpath smooth on {folder}: {summary['exit_0']} of {summary['programs']} exit 0; "
                        f"{summary['checked']} changed outputs checked apart, largest distance "
                        f"{summary['largest_distance_mm']:.4f} mm, {summary['runs_mismatch']} feed-run mismatches")
    for column in ("program", "exit", "last line"):
        table.add_column(column)
    for name, row in result["programs"].items():
        if row["exit"] != 0 or not row.get("check", {}).get("checked", True):
            table.add_row(name, str(row["exit"]), row.get("check", {}).get("why") or row["said"][-120:])
    Console().print(table)
    print(f"wrote {OUT / 'programs.json'}")
    return 0


@contextlib.contextmanager
def _single_thread():
    from threadpoolctl import threadpool_limits  # a scikit-learn dependency, so always installed

    with threadpool_limits(limits=1):
        yield


if __name__ == "__main__":
    sys.exit(main())
