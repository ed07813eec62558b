"""Quantization-aware training of one learned model of ``qat.models`` to INT8 on every shape (Sec. 5.1.2,
Table 4).

Run: python -m toolpath.stages.qat --model mcrl

Per shape: start from the trained FP32 weights, run QAT through PT2E (:mod:`toolpath.inference.qat`) on
the model's training settings (:func:`toolpath.pipeline.settings.qat_training`), convert, save the INT8
``.pt2``, reload it and check the outputs are identical, and score it on the same test programs as the
FP32 model with every Table 3 metric; then export the INT8 graph to ONNX (what ONNX Runtime and OpenVINO
run, :mod:`toolpath.inference.runtimes`) and score that file in each runtime.  A shape whose route fails
is recorded with the reason (``status: failed``) and the others go on; no file is written for it, and
the stage then exits non-zero (its metrics written), so DVC does not take it as done.

Writes the model's QAT metrics, keyed by shape (deterministic), and timing
(:class:`toolpath.pipeline.artifacts.Layout`).
"""

from __future__ import annotations

import torch

from toolpath.inference import qat_runs
from toolpath.models.registry import build
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import clean_dir, model_arg, progress


def _expected_seconds(layout: artifacts.Layout, shape: str, model: str) -> float:
    """The model's FP32 training time, a scheduling hint only (missing or unreadable: 0)."""
    try:
        return float(sum(artifacts.read_json(layout.train_timing(shape, model), "train")["train_seconds"]))
    except (artifacts.ArtifactError, KeyError, TypeError, ValueError):  # a hint: the schedule never changes results
        return 0.0


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    qcfg, layout = settings.plain(cfg.qat), settings.layout(cfg)
    name = model_arg(__doc__.split("\n")[0], argv, qcfg["models"]).model
    torch.set_num_threads(cfg.train.common.threads)
    torch.use_deterministic_algorithms(True)
    float_modules = settings.float_modules(cfg, name)
    known = {module for module, _ in build(settings.training(cfg, cfg.shapes[0], name)[0]).named_modules()}
    if unknown := [n for n in float_modules if n not in known]:
        # a misspelt name is a configuration error, refused before any file is touched
        raise SystemExit(f"params.yaml: qat.float_modules.{name}: the {name} network has no module {unknown[0]!r}")
    quantize_outputs = list(qcfg.get("quantize_outputs") or [])
    if unknown := [n for n in quantize_outputs if n not in cfg.models]:
        raise SystemExit(f"params.yaml: qat.quantize_outputs: {unknown[0]!r} is not a model of `models`")
    out_dir = clean_dir(layout.int8_dir(name))
    producer, threads = f"train@{name}", cfg.train.common.threads  # per job, whatever the workers
    parts = {shape: qat_runs.training_parts(artifacts.load_windows(layout.windows_file(shape), shape),
                                            qcfg["train_windows"], config.seed_for(cfg.seed, "qat", shape, "subset"))
             for shape in cfg.shapes}
    with tracking.stage_run(f"qat@{name}", config.flat(qcfg, "qat")):
        import mlflow

        fp32_tests = {shape: artifacts.read_json(layout.train_metrics(shape, name), producer)["test"]
                      for shape in cfg.shapes}
        jobs = [(name, layout.checkpoint(shape, name), producer, parts[shape],
                 settings.qat_training(cfg, shape, name), qcfg["freeze_last"], layout.int8_model(shape, name),
                 layout.int8_onnx(shape, name), threads, float_modules, bool(qcfg["quantize_conv1d"]),
                 bool(qcfg["reduce_range"]), name in quantize_outputs) for shape in cfg.shapes]
        outputs = qat_runs.run_all(jobs, settings.workers(cfg, "qat"),
                                   lambda k: _expected_seconds(layout, cfg.shapes[k], name),
                                   lambda done: progress(done, f"qat {name}", total=len(jobs)))
        report, timing = qat_runs.record(list(cfg.shapes), jobs, outputs, fp32_tests, out_dir)
        for shape in cfg.shapes:
            report[shape]["train_windows"] = int(len(parts[shape]["train"][0]))
        mlflow.log_metrics(qat_runs.mlflow_metrics(report))
        artifacts.write_json(report, layout.qat_metrics(name))
        artifacts.write_json(timing, layout.qat_timing(name))
        mlflow.log_dict(report, "qat.json")
        for shape in cfg.shapes:  # each shipped INT8 file as an MLflow ONNX model of this run
            if report[shape].get("status") == "ok" and layout.int8_onnx(shape, name).is_file():
                tracking.log_onnx_model(f"int8-{name}", layout.int8_onnx(shape, name), {"model": name, "shape": shape})
        qat_runs.stop_if_any_failed(report, f"qat@{name}", layout.qat_metrics(name), out_dir)


if __name__ == "__main__":
    main()
