"""Helpers shared by the stage modules: argument parsing, JSON output, progress bars."""

from __future__ import annotations

import argparse
import json
import math
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, TypeVar

from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

T = TypeVar("T")


def shape_arg(description: str, argv: list[str] | None, shapes: Iterable[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--shape", required=True, choices=list(shapes))
    return parser.parse_args(argv)


def clean_dir(path: Path) -> Path:
    """An empty directory at ``path`` (DVC outs are overwritten completely)."""
    if path.exists():
        shutil.rmtree(path)
    path.mkdir(parents=True)
    return path


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite(v) for v in value]
    return value


def write_json(data: dict, path: Path) -> None:
    """Deterministic JSON (sorted keys, fixed indentation, NaN/inf as null)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_finite(data), indent=2, sort_keys=True) + "\n", encoding="utf-8")


def progress(items: list[T], label: str) -> Iterator[T]:
    """Iterate with a rich progress bar on stderr."""
    columns = (TextColumn(label), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, transient=False) as bar:
        task = bar.add_task(label, total=len(items))
        for item in items:
            yield item
            bar.advance(task)


WINDOW_KEYS = ("windows", "label", "split", "program")


def load_arrays(path: Path, required: Iterable[str], what: str, producer: str) -> dict:
    """Every array of an ``.npz`` file, or exit with a message naming the file and the problem."""
    import numpy as np

    if not path.is_file():
        raise SystemExit(f"{path}: {what} file not found; run `dvc repro {producer}` first")
    try:
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise SystemExit(f"{path}: not a readable {what} file ({exc})") from None
    missing = [k for k in required if k not in arrays]
    if missing:
        raise SystemExit(f"{path}: malformed {what} file, missing {', '.join(missing)}")
    return arrays


def load_windows(path: Path) -> dict:
    """The arrays of a windows file, or exit with a message naming the file and the problem."""
    arrays = load_arrays(path, WINDOW_KEYS, "windows", "label")
    w = arrays["windows"]
    if w.ndim != 3 or w.shape[2] != 2 or len(arrays["label"]) != len(w) or len(arrays["split"]) != len(w):
        raise SystemExit(f"{path}: malformed windows file, windows {w.shape} do not match labels / split")
    return arrays


def write_rows(rows: list[dict], fields: Iterable[str], path: Path) -> None:
    """One CSV row per dict, the ``fields`` in order; floats to 6 significant digits."""
    import csv

    fields = list(fields)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(fields)
        for r in rows:
            writer.writerow([f"{r[k]:.6g}" if isinstance(r[k], float) else r[k] for k in fields])


def grouped_metrics(methods: dict, names: dict[str, str]) -> dict[str, float]:
    """``{mode: {encoding: {method: stats}}}`` flattened to ``mode.encoding.method.<name>`` for MLflow,
    ``names`` mapping each metric name to its key in ``stats``."""
    return {f"{mode}.{encoding}.{method}.{name}": stats[key]
            for mode, by_encoding in methods.items() for encoding, by_method in by_encoding.items()
            for method, stats in by_method.items() for name, key in names.items()}


def save_checkpoint(checkpoint: dict, path: Path) -> None:
    import torch

    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(checkpoint, path)


def load_checkpoint(path: Path) -> dict:
    import torch

    if not path.is_file():
        raise SystemExit(f"{path}: model file not found; run `dvc repro train` first")
    return torch.load(path, weights_only=True)
