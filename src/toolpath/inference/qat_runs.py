"""The qat stage's work as functions: the splits QAT trains on, one model on one shape quantised in a worker
process, every shape of a model side by side, and the model's record (Sec. 5.1.2, Table 4)."""

from __future__ import annotations

import traceback
from concurrent.futures import FIRST_COMPLETED, Executor, wait
from pathlib import Path

import numpy as np
import torch

from toolpath.inference.qat import quantize_one, ship_int8
from toolpath.pipeline import artifacts
from toolpath.pipeline.warm_pool import process_pool

TABLE3 = ("accuracy", "loss", "precision", "recall", "f1", "auc")


def training_parts(data: artifacts.WindowSet, subset: int | None, seed: int) -> dict[str, tuple]:
    """Every split as (float32 windows, class index 0-3); the training split cut to a seeded ``subset``."""
    parts = {s.label: (data.part(s)[0].astype(np.float32), artifacts.category_index(data.part(s)[1]))
             for s in artifacts.Split}
    if subset is not None and subset < len(parts["train"][0]):
        keep = np.sort(np.random.default_rng(seed).choice(len(parts["train"][0]), subset, replace=False))
        parts["train"] = (parts["train"][0][keep], parts["train"][1][keep])
    return parts


def worker(job: tuple) -> tuple[dict, float, str | None, tuple | None]:
    """One model's QAT on one shape in a worker process (spawned: fresh torch state, its share of the
    threads): (record, seconds, traceback of a failure, what :func:`ship` needs when an ONNX file is asked)."""
    name, fp32_file, producer, parts, train_settings, freeze_last, out, onnx, threads, float_modules, *flags = job
    conv1d, reduce, outputs = flags
    _threads(threads)
    artifacts.load_classifier(fp32_file, producer)  # a corrupt file stops the stage, it is no QAT result
    checkpoint = artifacts.load_checkpoint(fp32_file, producer)
    try:
        entry, seconds, predicted = quantize_one(name, checkpoint, parts, train_settings, freeze_last, out,
                                                 show_epochs=False, float_modules=float_modules,
                                                 quantize_conv1d=conv1d, reduce_range=reduce,
                                                 quantize_outputs=outputs)
    except Exception as exc:  # a route that fails is a result to report, not a crash
        return _failed(exc), 0.0, traceback.format_exc(), None
    return entry, seconds, None, None if onnx is None else (checkpoint, out, onnx, parts["test"], predicted, threads)


def ship(handoff: tuple) -> tuple[dict | None, str | None]:
    """:func:`~toolpath.inference.qat.ship_int8` in a worker process: (its fields of the record, None) or
    (a failed record, its traceback)."""
    _threads(handoff[-1])
    try:
        return ship_int8(*handoff), None
    except Exception as exc:  # a runtime route that fails is reported like a QAT route that fails
        return _failed(exc), traceback.format_exc()


def _threads(threads: int) -> None:
    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(True)


def _failed(exc: Exception) -> dict:
    return {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"[:2000]}


def run_all(jobs: list[tuple], workers: int, expected_seconds, progress) -> list[tuple]:
    """Every job in spawned workers, the longest expected first (``expected_seconds(index)``); results
    (record, seconds, failure traceback) in job order, the same output for any schedule.  A job's ONNX
    export and runtime scoring (:func:`ship`) is a task of its own, queued when its QAT ends: three shapes
    on two workers then finish nearly together instead of the third running alone."""
    with process_pool(workers) as pool:
        order = sorted(range(len(jobs)), key=lambda k: -expected_seconds(k))
        results: list = [None] * len(jobs)
        for _ in progress(_finished(pool, [pool.submit(worker, jobs[k]) for k in order], order, results)):
            pass
        return results


def _finished(pool: Executor, trained: list, order: list[int], results: list):
    """Yield each job's index once its record is whole, filling ``results``."""
    pending = dict(zip(trained, order, strict=True))
    shipping: dict = {}
    while pending:
        done, _ = wait(pending, return_when=FIRST_COMPLETED)
        for future in done:
            k = pending.pop(future)
            if k in shipping:  # the shipping task of job k
                entry, seconds, _ = results[k]
                shipped, failure = future.result()
                if failure is not None:
                    results[k] = (shipped, 0.0, failure)
                else:
                    results[k] = ({**entry, **shipped}, seconds, None)
                yield k
                continue
            entry, seconds, failure, handoff = future.result()
            results[k] = (entry, seconds, failure)
            if handoff is None:
                yield k
            else:
                shipping[k] = True
                pending[pool.submit(ship, handoff)] = k


def record(keys: list[str], jobs: list[tuple], outputs: list[tuple], fp32_tests: dict[str, dict],
           out_dir: Path) -> tuple[dict, dict]:
    """(entries, seconds) per key (a job's shape): each QAT entry beside its FP32 test figures and the
    accuracy drop; a failed job's traceback goes to ``<out_dir>/<key>.failed.txt``."""
    report, timing = {}, {}
    for name, (_, fp32_file, *_), (entry, seconds, failure) in zip(keys, jobs, outputs, strict=True):
        fp32 = fp32_tests[name]
        if failure is not None:
            (out_dir / f"{name}.failed.txt").write_text(failure)
        entry["fp32_test"] = {k: fp32[k] for k in TABLE3}
        entry["fp32_file_bytes"] = fp32_file.stat().st_size
        if entry["status"] == "ok":
            entry["accuracy_drop_points"] = 100.0 * (fp32["accuracy"] - entry["test"]["accuracy"])
        report[name] = entry
        timing[name] = {"qat_seconds": seconds}
    return report, timing


def mlflow_metrics(report: dict) -> dict[str, float]:
    """Each quantised entry's INT8 Table 3 figures and accuracy drops (per runtime too), under its key."""
    out = {}
    for name, entry in report.items():
        if not isinstance(entry, dict) or entry.get("status") != "ok":
            continue
        out |= {f"{name}.int8.{k}": entry["test"][k] for k in TABLE3}
        out[f"{name}.accuracy_drop_points"] = entry["accuracy_drop_points"]
        for runtime, row in entry.get("runtimes", {}).items():
            if "accuracy_drop_points" in row:
                out[f"{name}.{runtime}.accuracy_drop_points"] = row["accuracy_drop_points"]
    return out


def stop_if_any_failed(report: dict, stage: str, metrics_file, out_dir) -> None:
    """Exit non-zero (after the metrics are written) when an entry could not be quantised: the stage
    could not do its work, and DVC must not cache it as done."""
    if failed := [name for name, entry in report.items() if isinstance(entry, dict) and entry["status"] != "ok"]:
        raise SystemExit(f"{stage}: {', '.join(failed)} could not be quantised; the reasons are in "
                         f"{metrics_file} and {out_dir}/<shape>.failed.txt")
