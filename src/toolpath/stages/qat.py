"""Quantization-aware training of every learned model of one shape to INT8 (Sec. 5.1.2, Table 4).

Run: python -m toolpath.stages.qat --shape gear

For each model of ``qat.models``: start from the trained FP32 weights, run QAT through PT2E
(:mod:`toolpath.inference.qat`) on the model's training settings (:func:`toolpath.pipeline.settings.qat_training`),
convert, save the INT8 ``.pt2``, reload it and check the outputs are identical, and score
it on the same test programs as the FP32 model with every Table 3 metric; then export the INT8 graph
to ONNX (``<model>.onnx``: what ONNX Runtime and OpenVINO run, :mod:`toolpath.inference.runtimes`)
and score that file in each runtime.  A model whose route fails
is recorded with the reason (``status: failed``) and the other models go on; no file is written for
it, and the stage then exits non-zero (its metrics written), so DVC does not take it as done.

Writes the shape's QAT metrics (deterministic) and timing (:class:`toolpath.pipeline.artifacts.Layout`).
"""

from __future__ import annotations

import torch

from toolpath.inference import qat_runs
from toolpath.models.registry import build
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import clean_dir, progress, shape_arg


def _expected_seconds(layout: artifacts.Layout, shape: str, model: str) -> float:
    """The model's FP32 training time, a scheduling hint only (missing or unreadable: 0)."""
    try:
        return float(sum(artifacts.read_json(layout.train_timing(shape, model), "train")["train_seconds"]))
    except (artifacts.ArtifactError, KeyError, TypeError, ValueError):  # a hint: the schedule never changes results
        return 0.0


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    args = shape_arg(__doc__.split("\n")[0], argv, cfg.shapes)
    qcfg, layout = settings.plain(cfg.qat), settings.layout(cfg)
    torch.set_num_threads(cfg.train.common.threads)
    torch.use_deterministic_algorithms(True)
    parts = qat_runs.training_parts(artifacts.load_windows(layout.windows_file(args.shape), args.shape),
                                    qcfg["train_windows"], config.seed_for(cfg.seed, "qat", args.shape, "subset"))
    float_modules = {name: settings.float_modules(cfg, name) for name in qcfg["models"]}
    for name, names in float_modules.items():
        # a misspelt name is a configuration error, refused before any file is touched (QAT would
        # refuse it too, but as one failed model of a stage that exits 0)
        known = {module for module, _ in build(settings.training(cfg, args.shape, name)[0]).named_modules()}
        if unknown := [n for n in names if n not in known]:
            raise SystemExit(f"params.yaml: qat.float_modules.{name}: the {name} network has no module "
                             f"{unknown[0]!r}")
    quantize_outputs = list(qcfg.get("quantize_outputs") or [])
    if unknown := [name for name in quantize_outputs if name not in cfg.models]:
        raise SystemExit(f"params.yaml: qat.quantize_outputs: {unknown[0]!r} is not a model of `models`")
    out_dir = clean_dir(layout.int8_dir(args.shape))
    params = {**config.flat(qcfg, "qat"), **config.flat(cfg.train[args.shape], "schedule")}
    with tracking.stage_run(f"qat@{args.shape}", params, shape=args.shape):
        import mlflow

        producer, threads = f"train@{args.shape}", cfg.train.common.threads  # per job, whatever the workers
        fp32_tests = {name: artifacts.read_json(layout.train_metrics(args.shape, name), producer)["test"]
                      for name in qcfg["models"]}
        jobs = [(name, layout.checkpoint(args.shape, name), producer, parts,
                 settings.qat_training(cfg, args.shape, name), qcfg["freeze_last"], layout.int8_model(args.shape, name),
                 layout.int8_onnx(args.shape, name), threads,
                 float_modules[name], bool(qcfg["quantize_conv1d"]), bool(qcfg["reduce_range"]),
                 name in quantize_outputs) for name in qcfg["models"]]
        outputs = qat_runs.run_all(jobs, settings.workers(cfg, "qat"),
                                   lambda name: _expected_seconds(layout, args.shape, name),
                                   lambda jobs: progress(jobs, f"qat {args.shape}"))
        entries, timing = qat_runs.record(jobs, outputs, fp32_tests, out_dir)
        report = {"train_windows": int(len(parts["train"][0])), **entries}
        mlflow.log_metrics(qat_runs.mlflow_metrics(report))
        artifacts.write_json(report, layout.qat_metrics(args.shape))
        artifacts.write_json(timing, layout.qat_timing(args.shape))
        mlflow.log_dict(report, "qat.json")
        for name in qcfg["models"]:  # each shipped INT8 file as an MLflow ONNX model of this run
            if report[name].get("status") == "ok" and layout.int8_onnx(args.shape, name).is_file():
                tracking.log_onnx_model(f"int8-{name}", layout.int8_onnx(args.shape, name), {"model": name})
        qat_runs.stop_if_any_failed(report, args.shape, layout.qat_metrics(args.shape), out_dir)


if __name__ == "__main__":
    main()
