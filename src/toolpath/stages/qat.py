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

import multiprocessing
import traceback
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import torch

from toolpath.inference.qat import quantize_one
from toolpath.models.registry import build
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import clean_dir, progress, shape_arg

TABLE3 = ("accuracy", "loss", "precision", "recall", "f1", "auc")


def _worker(job: tuple) -> tuple[dict, float, str | None]:
    """One model in a worker process (spawned: fresh torch state, its share of the threads)."""
    name, fp32_file, producer, parts, train_settings, freeze_last, out, onnx, threads, float_modules, *flags = job
    conv1d, reduce, outputs = flags
    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(True)
    artifacts.load_classifier(fp32_file, producer)  # a corrupt file stops the stage, it is no QAT result
    checkpoint = artifacts.load_checkpoint(fp32_file, producer)
    try:
        entry, seconds = quantize_one(name, checkpoint, parts, train_settings, freeze_last, out, show_epochs=False,
                                      float_modules=float_modules, onnx=onnx, threads=threads,
                                      quantize_conv1d=conv1d, reduce_range=reduce, quantize_outputs=outputs)
        return entry, seconds, None
    except Exception as exc:  # a route that fails is a result to report, not a crash
        return {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"[:2000]}, 0.0, traceback.format_exc()


def _expected_seconds(layout: artifacts.Layout, shape: str, model: str) -> float:
    """The model's FP32 training time, a scheduling hint only (missing or unreadable: 0)."""
    try:
        return float(sum(artifacts.read_json(layout.train_timing(shape, model), "train")["train_seconds"]))
    except (artifacts.ArtifactError, KeyError, TypeError, ValueError):  # a hint: the schedule never changes results
        return 0.0


def training_parts(data: artifacts.WindowSet, subset: int | None, seed: int) -> dict[str, tuple]:
    """Every split as (float32 windows, class index 0-3); the training split cut to a seeded ``subset``."""
    parts = {s.label: (data.part(s)[0].astype(np.float32), artifacts.category_index(data.part(s)[1]))
             for s in artifacts.Split}
    if subset is not None and subset < len(parts["train"][0]):
        keep = np.sort(np.random.default_rng(seed).choice(len(parts["train"][0]), subset, replace=False))
        parts["train"] = (parts["train"][0][keep], parts["train"][1][keep])
    return parts


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    args = shape_arg(__doc__.split("\n")[0], argv, cfg.shapes)
    qcfg, layout = settings.plain(cfg.qat), settings.layout(cfg)
    torch.set_num_threads(cfg.train.common.threads)
    torch.use_deterministic_algorithms(True)
    parts = training_parts(artifacts.load_windows(layout.windows_file(args.shape), args.shape), qcfg["train_windows"],
                           config.seed_for(cfg.seed, "qat", args.shape, "subset"))
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
    report, timing = {"train_windows": int(len(parts["train"][0]))}, {}
    params = {**config.flat(qcfg, "qat"), **config.flat(cfg.train[args.shape], "schedule")}
    with tracking.stage_run(f"qat@{args.shape}", params, shape=args.shape):
        import mlflow

        jobs, fp32_tests = [], {}
        for name in qcfg["models"]:
            producer = f"train@{args.shape}"
            fp32_tests[name] = artifacts.read_json(layout.train_metrics(args.shape, name), producer)["test"]
            threads = max(1, cfg.train.common.threads // qcfg["workers"])
            jobs.append((name, layout.checkpoint(args.shape, name), producer, parts,
                         settings.qat_training(cfg, args.shape, name), qcfg["freeze_last"],
                         layout.int8_model(args.shape, name),
                         layout.int8_onnx(args.shape, name), threads,
                         float_modules[name], bool(qcfg["quantize_conv1d"]), bool(qcfg["reduce_range"]),
                         name in quantize_outputs))
        # models are independent: spawned workers, the longest first so two workers finish together;
        # results are collected in config order (the same output for any schedule)
        with ProcessPoolExecutor(qcfg["workers"], mp_context=multiprocessing.get_context("spawn")) as pool:
            futures = {job[0]: pool.submit(_worker, job) for job in
                       sorted(jobs, key=lambda job: -_expected_seconds(layout, args.shape, job[0]))}
            outputs = [futures[job[0]].result() for job in progress(jobs, f"qat {args.shape}")]
        for (name, fp32_file, *_), (entry, seconds, failure) in zip(jobs, outputs, strict=True):
            fp32 = fp32_tests[name]
            if failure is not None:
                (out_dir / f"{name}.failed.txt").write_text(failure)
            entry["fp32_test"] = {k: fp32[k] for k in TABLE3}
            entry["fp32_file_bytes"] = fp32_file.stat().st_size
            if entry["status"] == "ok":
                entry["accuracy_drop_points"] = 100.0 * (fp32["accuracy"] - entry["test"]["accuracy"])
                mlflow.log_metrics({f"{name}.int8.{k}": entry["test"][k] for k in TABLE3})
                mlflow.log_metric(f"{name}.accuracy_drop_points", entry["accuracy_drop_points"])
                for runtime, row in entry.get("runtimes", {}).items():
                    if "accuracy_drop_points" in row:
                        mlflow.log_metric(f"{name}.{runtime}.accuracy_drop_points", row["accuracy_drop_points"])
            report[name] = entry
            timing[name] = {"qat_seconds": seconds}
        artifacts.write_json(report, layout.qat_metrics(args.shape))
        artifacts.write_json(timing, layout.qat_timing(args.shape))
        mlflow.log_dict(report, "qat.json")
        stop_if_any_failed(report, args.shape, layout.qat_metrics(args.shape), out_dir)


def stop_if_any_failed(report: dict, shape: str, metrics_file, out_dir) -> None:
    """Exit non-zero (after the metrics are written) when a model could not be quantised: the stage
    could not do its work, and DVC must not cache it as done."""
    if failed := [name for name, entry in report.items() if isinstance(entry, dict) and entry["status"] != "ok"]:
        raise SystemExit(f"qat@{shape}: {', '.join(failed)} could not be quantised; the reasons are in "
                         f"{metrics_file} and {out_dir}/<model>.failed.txt")


if __name__ == "__main__":
    main()
