"""Helpers shared by the stage modules: argument parsing, progress bars, MLflow metric names.  Files
between stages are :mod:`toolpath.pipeline.artifacts`."""

from __future__ import annotations

import argparse
import shutil
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import TypeVar

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from toolpath.pipeline.warm_pool import process_pool

T = TypeVar("T")
R = TypeVar("R")


def shape_arg(description: str, argv: list[str] | None, shapes: Iterable[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--shape", required=True, choices=list(shapes))
    return parser.parse_args(argv)


def model_arg(description: str, argv: list[str] | None, models: Iterable[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--model", required=True, choices=list(models))
    return parser.parse_args(argv)


def clean_dir(path: Path) -> Path:
    """An empty directory at ``path`` (DVC outs are overwritten completely)."""
    if path.exists():
        shutil.rmtree(path)
    path.mkdir(parents=True)
    return path


def progress(items: Iterable[T], label: str, total: int | None = None) -> Iterator[T]:
    """Iterate with a rich progress bar on stderr (``total``: for items without a length)."""
    columns = (TextColumn(label), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, transient=False) as bar:
        task = bar.add_task(label, total=len(items) if total is None else total)
        for item in items:
            yield item
            bar.advance(task)


def pool_map(fn: Callable[[T], R], jobs: list[T], workers: int, label: str) -> list[R]:
    """``[fn(job) for job in jobs]`` over ``workers`` processes, in job order whatever the worker count,
    with a progress bar.  ``dvc repro`` runs one stage at a time, so a one-process stage leaves a core
    idle.  Not forked from the stage, which holds MLflow's threads (and maybe torch's): forked by the warm
    server, else spawned (:func:`~toolpath.pipeline.warm_pool.process_pool`)."""
    if workers <= 1:
        return [fn(job) for job in progress(jobs, label)]
    with process_pool(workers) as pool:
        futures = [pool.submit(fn, job) for job in jobs]
        return [f.result() for f in progress(futures, label)]


def grouped_metrics(methods: dict, names: dict[str, str]) -> dict[str, float]:
    """``{mode: {encoding: {method: stats}}}`` flattened to ``mode.encoding.method.<name>`` for MLflow,
    ``names`` mapping each metric name to its key in ``stats``."""
    return {f"{mode}.{encoding}.{method}.{name}": stats[key]
            for mode, by_encoding in methods.items() for encoding, by_method in by_encoding.items()
            for method, stats in by_method.items() for name, key in names.items()}
