"""Inference benchmark for Table 4: FP32 and INT8 in torch, ONNX Runtime and OpenVINO, beside the exact rule.
Run: python -m toolpath.stages.benchmark (also ``make bench``). Per model: latency at batch 1, throughput at
``benchmark.batch`` (and ``large_batch`` if set), the time to classify each shape's whole test split, and the file
sizes; FP32 eager, INT8 eager (the reference graph) with ``benchmark.reference_int8``, FP32 and INT8 compiled with
inductor for ``benchmark.compile`` (30-65 s per graph), and in ONNX Runtime and OpenVINO the FP32 network (exported
here) and the qat stage's QDQ INT8 file. The INT8 runtime shipped per model is the fastest at ``benchmark.batch``
among those whose INT8 file lost at most ``benchmark.max_drop_points`` of test accuracy on every shape; each shape's
test split is timed for FP32 eager and the shipped runtime's FP32 and INT8. Timings use the gear models (the
architectures, hence the speed, are every shape's). Plus MCRL's per-branch profile, each runtime's per-operator
profile of every ONNX file and, for ``benchmark.recurrent_forms``, the recurrences as ONNX nodes beside the shipped
file (Table 4d). Writes the inference metrics (timings vary between runs by nature), logs them to MLflow. Never a test.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import torch

from toolpath.inference import table4
from toolpath.inference.paper import TABLE4
from toolpath.inference.timing import bench_model, bench_rule, branch_profile, machine, onnx_runners, shipped, threads
from toolpath.models.registry import parameter_count
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.artifacts import Split
from toolpath.pipeline.workers import progress


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    bcfg, qcfg, layout = settings.plain(cfg.benchmark), settings.plain(cfg.qat), settings.layout(cfg)
    shapes = list(cfg.shapes)

    def fp32(shape: str, name: str) -> torch.nn.Module:
        return artifacts.load_classifier(layout.checkpoint(shape, name), f"train@{name}").network_.eval()

    def int8(shape: str, name: str) -> torch.nn.Module | None:
        path = layout.int8_model(shape, name)
        # torch's INT8 graph is timed eagerly (the reference graph) or compiled, or not at all
        wanted = bcfg["reference_int8"] or name in bcfg["compile"]
        return artifacts.load_int8(path, f"qat@{name}") if wanted and path.is_file() else None

    tests = {s: torch.as_tensor(artifacts.load_windows(layout.windows_file(s), s).part(Split.TEST)[0]) for s in shapes}
    inputs = table4.draw_inputs(tests[shapes[0]], bcfg["batch"], bcfg["large_batch"],
                                config.seed_for(cfg.seed, "benchmark"))  # large_batch null: no large row
    torch.use_deterministic_algorithms(False)  # inference only; allow the fastest kernels
    form = "the INT8 graph's (1-D convolutions as 2-D)" if qcfg["quantize_conv1d"] else "the network's"
    setup = {k: bcfg[k] for k in ("repeats", "warmup", "split_repeats", "batch", "large_batch", "reference_int8")}
    setup |= {"timing_shape": shapes[0], "compiled": bcfg["compile"], "fp32_onnx_form": form}
    result: dict = {"setup": {**machine(bcfg["threads"]), **setup}, "models": {}, "paper_table4_s": TABLE4}
    with tracking.stage_run("benchmark", {**config.flat(bcfg, "benchmark"), "qat.quantize_conv1d":
                                          qcfg["quantize_conv1d"]}), threads(bcfg["threads"]):
        import mlflow

        qat_metrics = {n: artifacts.read_json(layout.qat_metrics(n), f"qat@{n}") if n in qcfg["models"] else {}
                       for n in bcfg["models"]}
        scratch = Path(tempfile.mkdtemp(prefix="benchmark-onnx-"))
        # the FP32 network in the ONNX runtimes: the first shape's (the architecture, hence the speed, is every
        # shape's) in its INT8 graph's form, exported before any timing; INT8: each shape's own qat file
        fp32_files = {name: scratch / f"{name}.fp32.onnx" for name in bcfg["models"]}
        table4.export_all([(layout.checkpoint(shapes[0], name), f"train@{name}", settings.float_modules(cfg, name),
                            bool(qcfg["quantize_conv1d"]), inputs["batch"][:2], fp32_files[name])
                           for name in bcfg["models"]], bcfg["threads"])
        for name in progress(list(bcfg["models"]), "benchmark"):
            fp32_onnx = fp32_files[name]

            def onnx(shape: str, n: str = name, fp32_file: Path = fp32_onnx, runtimes: tuple | None = None) -> dict:
                return onnx_runners({"fp32": fp32_file, "int8": layout.int8_onnx(shape, n)}, bcfg["threads"], runtimes)

            def choose(entry: dict, n: str = name) -> dict:
                return shipped(entry, {s: qat_metrics[n].get(s, {}) for s in shapes}, bcfg["max_drop_points"])

            entry = bench_model(lambda s, n=name: fp32(s, n), lambda s, n=name: int8(s, n), shapes, tests, inputs,
                                bcfg, name in bcfg["compile"], onnx, choose)
            entry["parameters"] = parameter_count(fp32(shapes[0], name))
            entry |= table4.files_and_profiles(layout.checkpoint(shapes[0], name), layout.int8_model(shapes[0], name),
                                               fp32_onnx, layout.int8_onnx(shapes[0], name),
                                               layout.qat_metrics(name), bcfg["threads"], inputs["batch"].numpy())
            if name in bcfg["recurrent_forms"]:
                entry["recurrent_forms"] = table4.recurrent_forms(
                    fp32(shapes[0], name), layout.checkpoint(shapes[0], name), fp32_onnx,
                    settings.float_modules(cfg, name), bool(qcfg["quantize_conv1d"]), inputs["batch"], bcfg)
            result["models"][name] = entry
        shutil.rmtree(scratch, ignore_errors=True)
        rule = artifacts.load_classifier(layout.checkpoint(shapes[0], "rule"), "train@rule")
        result["rule"] = bench_rule(rule, shapes, tests, inputs, bcfg)
        if "mcrl" in bcfg["models"]:
            profile = branch_profile(fp32(shapes[0], "mcrl"), inputs["batch"], bcfg["repeats"])
            result["mcrl_branch_profile_ms"] = {k: 1e3 * v for k, v in profile.items()}
        artifacts.write_json(result, layout.inference_metrics)
        # per-operator shares stay in the JSON: operator names such as "FullyConnected [jit_gemm_I8]" are no metric keys
        mlflow.log_metrics({k: v for k, v in config.flat(result["models"]).items()
                            if isinstance(v, int | float) and ".share_by_op." not in k})
        mlflow.log_artifact(str(layout.inference_metrics))


if __name__ == "__main__":
    main()
