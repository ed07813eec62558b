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


def load_windows(path: Path) -> dict:
    """The arrays of a windows file, or exit with a message naming the file and the problem."""
    import numpy as np

    if not path.is_file():
        raise SystemExit(f"{path}: windows file not found; run `dvc repro label` first")
    try:
        with np.load(path) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise SystemExit(f"{path}: not a readable windows file ({exc})") from None
    missing = [k for k in WINDOW_KEYS if k not in arrays]
    if missing:
        raise SystemExit(f"{path}: malformed windows file, missing {', '.join(missing)}")
    w = arrays["windows"]
    if w.ndim != 3 or w.shape[2] != 2 or len(arrays["label"]) != len(w) or len(arrays["split"]) != len(w):
        raise SystemExit(f"{path}: malformed windows file, windows {w.shape} do not match labels / split")
    return arrays


def save_checkpoint(checkpoint: dict, path: Path) -> None:
    import torch

    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(checkpoint, path)


def load_checkpoint(path: Path) -> dict:
    import torch

    if not path.is_file():
        raise SystemExit(f"{path}: model file not found; run `dvc repro train` first")
    return torch.load(path, weights_only=True)
