"""Quantization-aware training of every learned model of one shape to INT8 (Sec. 5.1.2, Table 4).

Run: python -m toolpath.stages.qat --shape gear

For each model of ``qat.models``: start from the trained FP32 weights (``models/<shape>/<model>.pt``),
run QAT through PT2E (:mod:`toolpath.training.qat`) on the shape's Table 2 schedule, convert, save
``<paths.models>/int8/<shape>/<model>.pt2``, reload it and check the outputs are identical, and score
it on the same test programs as the FP32 model with every Table 3 metric.  A model whose route fails
is recorded with the reason (``status: failed``) and the stage moves on; no file is written for it.

Writes ``<paths.metrics>/qat/<shape>.json`` (deterministic) and ``<paths.timing>/qat/<shape>.json``.
"""

from __future__ import annotations

import json
import multiprocessing
import time
import traceback
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import torch
from omegaconf import OmegaConf

from toolpath import config, tracking
from toolpath.shapes.synth import SHAPES
from toolpath.stages._common import clean_dir, load_checkpoint, load_windows, progress, shape_arg, write_json
from toolpath.training import qat
from toolpath.training.classifier import from_checkpoint
from toolpath.training.loop import TrainSettings, predict_logits
from toolpath.training.metrics import classification_metrics
from toolpath.training.progress import EpochBar

TABLE3 = ("accuracy", "loss", "precision", "recall", "f1", "auc")


def _fp32_test(metrics_dir: Path, shape: str, model: str) -> dict:
    path = metrics_dir / "train" / shape / f"{model}.json"
    if not path.is_file():
        raise SystemExit(f"{path}: FP32 metrics not found; run `dvc repro train` first")
    return json.loads(path.read_text())["test"]


def quantize_one(name: str, checkpoint: dict, parts: dict, settings: TrainSettings, freeze_last: int,
                 out: Path, show_epochs: bool = True) -> tuple[dict, float]:
    """QAT, convert, save, reload-check and score one model; returns (metrics, seconds)."""
    clf = from_checkpoint(checkpoint)
    started = time.perf_counter()
    if show_epochs:
        with EpochBar(f"qat {name}", settings.epochs) as bar:
            result = qat.train_qat(clf.network_, *parts["train"], settings, *parts["val"],
                                   freeze_last=freeze_last, on_epoch=bar.update)
    else:
        result = qat.train_qat(clf.network_, *parts["train"], settings, *parts["val"], freeze_last=freeze_last)
    seconds = time.perf_counter() - started
    X_test = torch.as_tensor(parts["test"][0])
    logits = predict_logits(result.model, X_test)
    size = qat.save(result.model, X_test[:2], out)
    reloaded = predict_logits(qat.load(out), X_test)
    proba = torch.softmax(logits, dim=1).numpy()
    metrics = classification_metrics(parts["test"][1] + 1, proba)
    return {"status": "ok", "test": metrics, "reload_identical": bool(torch.equal(logits, reloaded)),
            "file_bytes": size, "tensor_bytes": qat.tensor_bytes(result.model),
            "fp32_tensor_bytes": qat.tensor_bytes(from_checkpoint(checkpoint).network_),
            "ops": qat.op_precision(result.model), "epochs": len(result.history)}, seconds


def _worker(job: tuple) -> tuple[dict, float, str | None]:
    """One model in a worker process (spawned: fresh torch state, its share of the threads)."""
    name, fp32_file, parts, settings, freeze_last, out, threads = job
    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(True)
    try:
        entry, seconds = quantize_one(name, load_checkpoint(fp32_file), parts, settings, freeze_last, out,
                                      show_epochs=False)
        return entry, seconds, None
    except Exception as exc:  # a route that fails is a result to report, not a crash
        return {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"[:2000]}, 0.0, traceback.format_exc()


def main(argv: list[str] | None = None) -> None:
    args = shape_arg(__doc__.split("\n")[0], argv, SHAPES)
    cfg = config.load()
    qcfg = OmegaConf.to_container(cfg.qat, resolve=True)
    torch.set_num_threads(cfg.train.common.threads)
    torch.use_deterministic_algorithms(True)
    data = load_windows(Path(cfg.paths.windows) / f"{args.shape}.npz")
    windows, index = data["windows"].astype(np.float32), (data["label"] - 1).astype(np.int64)
    parts = {name: (windows[data["split"] == k], index[data["split"] == k])
             for k, name in enumerate(("train", "val", "test"))}
    if qcfg["train_windows"] is not None and qcfg["train_windows"] < len(parts["train"][0]):
        rng = np.random.default_rng(config.seed_for(cfg.seed, "qat", args.shape, "subset"))
        keep = np.sort(rng.choice(len(parts["train"][0]), qcfg["train_windows"], replace=False))
        parts["train"] = (parts["train"][0][keep], parts["train"][1][keep])
    schedule = OmegaConf.to_container(cfg.train[args.shape])
    models_dir = Path(cfg.paths.models) / args.shape
    out_dir = clean_dir(Path(cfg.paths.models) / "int8" / args.shape)
    metrics_dir = Path(cfg.paths.metrics)
    report, timing = {"train_windows": int(len(parts["train"][0]))}, {}
    params = {**config.flat(qcfg, "qat"), **config.flat(schedule, "schedule")}
    with tracking.stage_run(f"qat@{args.shape}", params, shape=args.shape):
        import mlflow

        jobs, fp32_tests = [], {}
        for name in qcfg["models"]:
            fp32_tests[name] = _fp32_test(metrics_dir, args.shape, name)
            if not (models_dir / f"{name}.pt").is_file():
                raise SystemExit(f"{models_dir / f'{name}.pt'}: model file not found; run `dvc repro train` first")
            settings = TrainSettings(lr=schedule["lr"] * qcfg["lr_scale"], decay_rate=schedule["decay_rate"],
                                     decay_steps=schedule["decay_steps"], batch_size=schedule["batch_size"],
                                     epochs=qcfg["epochs"], weight_decay=cfg.train.common.weight_decay,
                                     seed=config.seed_for(cfg.seed, "qat", args.shape, name))
            threads = max(1, cfg.train.common.threads // qcfg["workers"])
            jobs.append((name, models_dir / f"{name}.pt", parts, settings, qcfg["freeze_last"],
                         out_dir / f"{name}.pt2", threads))
        # models are independent: spawned workers, results in submission order (same output for any order)
        with ProcessPoolExecutor(qcfg["workers"], mp_context=multiprocessing.get_context("spawn")) as pool:
            futures = [pool.submit(_worker, job) for job in jobs]
            outputs = [future.result() for future in progress(futures, f"qat {args.shape}")]
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
            report[name] = entry
            timing[name] = {"qat_seconds": seconds}
        write_json(report, metrics_dir / "qat" / f"{args.shape}.json")
        write_json(timing, Path(cfg.paths.timing) / "qat" / f"{args.shape}.json")
        mlflow.log_dict(report, "qat.json")


if __name__ == "__main__":
    main()
