"""Inference benchmark for Table 4: FP32 and INT8 in torch, ONNX Runtime and OpenVINO, beside the exact rule.

Run: python -m toolpath.stages.benchmark   (also ``make bench``)

Per model: latency at batch 1, throughput at ``benchmark.batch`` (and ``large_batch`` if set), the time to
classify each shape's whole test split, and the model file sizes; FP32 eager for every model and INT8
eager (the reference graph) with ``benchmark.reference_int8``, FP32 and INT8 compiled with inductor
for ``benchmark.compile`` (30-65 s of compilation per graph here), and in ONNX Runtime and OpenVINO the
FP32 network (exported here) and the qat stage's QDQ INT8 file.  The INT8 runtime shipped per model is
the fastest at batch ``benchmark.batch`` among those whose INT8 file lost at most ``benchmark.max_drop_points`` of test
accuracy on every shape (the qat stage scores each runtime); each shape's whole test split is timed
for FP32 eager and the shipped runtime's FP32 and INT8.  Timings use the gear models (the architectures, hence the
speed, are the same for every shape); the test-split times load each shape's own models.  Plus a
per-branch profile of MCRL, and each runtime's per-operator profile of every FP32 and INT8 ONNX file
(what stays float).  Writes the inference metrics (DVC metrics; timings vary between runs by
nature) and logs them to MLflow.  A benchmark, never a test.
"""

from __future__ import annotations

import multiprocessing
import shutil
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import torch

from toolpath.inference.qat import fp32_twin
from toolpath.inference.runtimes import RUNTIMES, export_onnx, op_profile
from toolpath.inference.timing import bench_model, bench_rule, branch_profile, machine, onnx_runners, shipped, threads
from toolpath.models.registry import parameter_count
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.artifacts import Split
from toolpath.pipeline.workers import progress
from toolpath.reports.paper import TABLE4


def _export_fp32(job: tuple) -> int:
    """One FP32 network as ONNX in its INT8 graph's form (in a worker process, on one thread)."""
    checkpoint, producer, float_modules, quantize_conv1d, example, out = job
    torch.set_num_threads(1)
    net = artifacts.load_classifier(checkpoint, producer).network_.eval()
    return export_onnx(fp32_twin(net, float_modules, quantize_conv1d), example, out)


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    bcfg, layout, shapes = settings.plain(cfg.benchmark), settings.layout(cfg), list(cfg.shapes)
    qcfg = settings.plain(cfg.qat)

    def fp32(shape: str, name: str) -> torch.nn.Module:
        return artifacts.load_classifier(layout.checkpoint(shape, name), f"train@{shape}").network_.eval()

    def int8(shape: str, name: str) -> torch.nn.Module | None:
        path = layout.int8_model(shape, name)
        # torch's INT8 graph is timed eagerly (the reference graph) or compiled, or not at all
        wanted = bcfg["reference_int8"] or name in bcfg["compile"]
        return artifacts.load_int8(path, f"qat@{shape}") if wanted and path.is_file() else None

    tests = {s: torch.as_tensor(artifacts.load_windows(layout.windows_file(s), s).part(Split.TEST)[0]) for s in shapes}
    draws = torch.Generator().manual_seed(config.seed_for(cfg.seed, "benchmark"))
    pool = tests[shapes[0]]
    large = bcfg["large_batch"]  # null: no large-batch row (the default profile)
    pick = torch.randint(0, len(pool), (max(bcfg["batch"], large or 0),), generator=draws)
    inputs = {"b1": pool[pick[:1]], "batch": pool[pick[: bcfg["batch"]]]}
    if large:
        inputs["large"] = pool[pick[:large]]
    torch.use_deterministic_algorithms(False)  # inference only; allow the fastest kernels
    setup = {k: bcfg[k] for k in ("repeats", "warmup", "split_repeats", "batch", "large_batch", "reference_int8")}
    result: dict = {"setup": {**machine(bcfg["threads"]), **setup, "timing_shape": shapes[0],
                              "compiled": bcfg["compile"],
                              "fp32_onnx_form": "the INT8 graph's (1-D convolutions as 2-D)" if qcfg["quantize_conv1d"]
                              else "the network's"}, "models": {}, "paper_table4_s": TABLE4}
    params = {**config.flat(bcfg, "benchmark"), "qat.quantize_conv1d": qcfg["quantize_conv1d"]}
    with tracking.stage_run("benchmark", params), threads(bcfg["threads"]):
        import mlflow

        qat_metrics = {s: artifacts.read_json(layout.qat_metrics(s), f"qat@{s}") for s in shapes}
        scratch = Path(tempfile.mkdtemp(prefix="benchmark-onnx-"))
        # the FP32 network in the ONNX runtimes: the first shape's (the architecture, hence the speed, is every
        # shape's) in its INT8 graph's form; INT8: each shape's own qat file.  The exports (up to 15 s each for
        # the unrolled recurrent models) run before any timing, in parallel processes.
        fp32_files = {name: scratch / f"{name}.fp32.onnx" for name in bcfg["models"]}
        jobs = [(layout.checkpoint(shapes[0], name), f"train@{shapes[0]}",
                 settings.float_modules(cfg, name), bool(qcfg["quantize_conv1d"]),
                 inputs["batch"][:2], fp32_files[name]) for name in bcfg["models"]]
        with ProcessPoolExecutor(bcfg["threads"], mp_context=multiprocessing.get_context("spawn")) as exporters:
            list(exporters.map(_export_fp32, jobs))
        for name in progress(list(bcfg["models"]), "benchmark"):
            fp32_onnx = fp32_files[name]

            def onnx(shape: str, n: str = name, fp32_file: Path = fp32_onnx, runtimes: tuple | None = None) -> dict:
                return onnx_runners({"fp32": fp32_file, "int8": layout.int8_onnx(shape, n)}, bcfg["threads"], runtimes)

            def choose(entry: dict, n: str = name) -> dict:
                return shipped(entry, {s: qat_metrics[s].get(n, {}) for s in shapes}, bcfg["max_drop_points"])

            entry = bench_model(lambda s, n=name: fp32(s, n), lambda s, n=name: int8(s, n), shapes, tests, inputs,
                                bcfg, name in bcfg["compile"], onnx, choose)
            entry["parameters"] = parameter_count(fp32(shapes[0], name))
            entry["fp32_file_bytes"] = layout.checkpoint(shapes[0], name).stat().st_size
            int8_path, int8_onnx = layout.int8_model(shapes[0], name), layout.int8_onnx(shapes[0], name)
            entry["int8_file_bytes"] = int8_path.stat().st_size if int8_path.is_file() else None
            entry["fp32_onnx_file_bytes"] = fp32_onnx.stat().st_size
            entry["int8_onnx_file_bytes"] = int8_onnx.stat().st_size if int8_onnx.is_file() else None
            if not int8_path.is_file():
                entry["int8_missing"] = f"{int8_path} not found (see {layout.qat_metrics(shapes[0])})"
            if int8_onnx.is_file():  # why INT8 is or is not faster: each runtime's profile of both files
                batch = inputs["batch"].numpy()
                entry["op_profile"] = {r: {p: op_profile(f, r, bcfg["threads"], batch)
                                           for p, f in (("fp32", fp32_onnx), ("int8", int8_onnx))} for r in RUNTIMES}
            result["models"][name] = entry
        shutil.rmtree(scratch, ignore_errors=True)
        rule_file = layout.checkpoint(shapes[0], "rule")
        rule = artifacts.load_classifier(rule_file, f"train@{shapes[0]}")
        result["rule"] = bench_rule(rule, shapes, tests, inputs, bcfg)
        if "mcrl" in bcfg["models"]:
            result["mcrl_branch_profile_ms"] = {k: 1e3 * v for k, v in
                                                branch_profile(fp32(shapes[0], "mcrl"), inputs["batch"],
                                                               bcfg["repeats"]).items()}
        artifacts.write_json(result, layout.inference_metrics)
        # per-operator shares stay in the JSON: operator names such as "FullyConnected [jit_gemm_I8]" are no metric keys
        mlflow.log_metrics({k: v for k, v in config.flat(result["models"]).items()
                            if isinstance(v, int | float) and ".share_by_op." not in k})
        mlflow.log_artifact(str(layout.inference_metrics))


if __name__ == "__main__":
    main()
