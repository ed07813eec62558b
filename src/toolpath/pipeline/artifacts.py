"""The files stages pass to one another: one typed description each (path, schema, load, save).

Every path derives from ``conf/paths`` through :class:`Layout`; nothing else in the code spells a path
below those roots, a split code or a label encoding.  ``dvc.yaml`` declares the same files as DVC deps
and outs (``tests/test_artifacts.py`` checks that every path here is declared there).  A file that is
missing or malformed stops the stage with one line naming the file and the stage that makes it.

Encodings: :class:`Split` codes per window (0 train, 1 val, 2 test); labels are Table 1 categories 1-4
everywhere outside a network (:data:`CATEGORIES`); only a network's output index is 0-3 (:func:`category_index`).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from enum import IntEnum
from pathlib import Path
from typing import Any

import numpy as np

from toolpath.pipeline.layout import Layout

__all__ = ["CATEGORIES", "ArtifactError", "Layout", "SmoothedSet", "Split", "WindowSet", "category_index",
           "load_arrays", "load_checkpoint", "load_classifier", "load_int8", "load_predictions", "load_smoothed",
           "load_windows", "read_json", "read_rows", "save_checkpoint", "save_predictions", "save_smoothed",
           "save_windows", "write_curves", "write_json", "write_rows"]


class Split(IntEnum):
    """The split code stored per window of the windows file (a window's whole program is in one split)."""
    TRAIN, VAL, TEST = 0, 1, 2

    @property
    def label(self) -> str:
        """'train', 'val' or 'test' (the keys of metrics files)."""
        return ("train", "val", "test")[self]


CATEGORIES = np.array([1, 2, 3, 4])  # Table 1's roughness categories, the labels of the windows file


def category_index(labels: np.ndarray) -> np.ndarray:
    """Categories 1-4 as a network's class index 0-3."""
    return np.searchsorted(CATEGORIES, np.asarray(labels)).astype(np.int64)


class ArtifactError(SystemExit):
    """A file between stages is missing or malformed: the message names it and the stage to rerun."""

    def __init__(self, path: Path, problem: str, producer: str) -> None:
        super().__init__(f"{path}: {problem}; run `dvc repro {producer}`")
        self.path, self.problem, self.producer = path, problem, producer

    def __reduce__(self) -> tuple:  # raised in a pool worker, it reaches the stage whole
        return (ArtifactError, (self.path, self.problem, self.producer))


# ---- arrays --------------------------------------------------------------------------------------
def load_arrays(path: Path, required: Iterable[str], what: str, producer: str) -> dict[str, np.ndarray]:
    """Every array of an ``.npz`` file; missing, unreadable or incomplete files stop with one line."""
    import zipfile

    if not path.is_file():
        raise ArtifactError(path, f"{what} file not found", producer)
    try:  # our own handle: np.load leaves its own open when the archive is corrupt
        with path.open("rb") as fh, np.load(fh) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise ArtifactError(path, f"not a readable {what} file ({exc})", producer) from None
    missing = [k for k in required if k not in arrays]
    if missing:
        raise ArtifactError(path, f"malformed {what} file, missing {', '.join(missing)}", producer)
    return arrays


@dataclass(frozen=True)
class WindowSet:
    """One shape's labelled windows (the generate stage's output).

    ``windows`` (N, 50, 2) float32 relative to each window's first point, ``origin`` (N, 2), ``label``
    (Table 1 category 1-4), ``split`` (:class:`Split` codes), ``program`` (index into
    ``program_files``), ``first_line`` (source line of the window's first point), ``local_curvature``.
    """

    windows: np.ndarray
    origin: np.ndarray
    local_curvature: np.ndarray
    label: np.ndarray
    program: np.ndarray
    first_line: np.ndarray
    split: np.ndarray
    program_files: np.ndarray

    def part(self, split: Split) -> tuple[np.ndarray, np.ndarray]:
        """(windows, labels) of one split."""
        keep = self.split == split
        return self.windows[keep], self.label[keep]

    def parts(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """(windows, labels) of every split, keyed 'train', 'val', 'test'."""
        return {s.label: self.part(s) for s in Split}


def save_windows(windows: WindowSet, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **{f.name: getattr(windows, f.name) for f in fields(WindowSet)})


def load_windows(path: Path, shape: str | None = None) -> WindowSet:
    """A windows file, checked against :class:`WindowSet`'s schema."""
    producer = f"generate@{shape}" if shape else "generate"
    arrays = load_arrays(path, [f.name for f in fields(WindowSet)], "windows", producer)
    w = arrays["windows"]
    n = len(w)
    if w.ndim != 3 or w.shape[2] != 2 or any(len(arrays[k]) != n for k in ("label", "split", "program")):
        raise ArtifactError(path, f"malformed windows file, windows {w.shape} do not match labels / split", producer)
    if n and (not np.isin(arrays["label"], CATEGORIES).all() or not np.isin(arrays["split"], list(Split)).all()):
        raise ArtifactError(path, "malformed windows file, labels outside 1-4 or split codes outside 0-2", producer)
    return WindowSet(**{f.name: arrays[f.name] for f in fields(WindowSet)})


@dataclass(frozen=True)
class SmoothedSet:
    """Every smoothed window of the optimize stage: points (R, n, 2) float64 and, per row, the window
    index into the shape's windows file, the method, the fidelity mode and the encoding."""

    points: np.ndarray
    window: np.ndarray
    method: np.ndarray
    mode: np.ndarray
    encoding: np.ndarray


def save_smoothed(smoothed: SmoothedSet, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **{f.name: getattr(smoothed, f.name) for f in fields(SmoothedSet)})


def load_smoothed(path: Path, shape: str | None = None) -> SmoothedSet:
    producer = f"optimize@{shape}" if shape else "optimize"
    arrays = load_arrays(path, [f.name for f in fields(SmoothedSet)], "smoothed-windows", producer)
    return SmoothedSet(**{f.name: arrays[f.name] for f in fields(SmoothedSet)})


def save_predictions(arrays: Mapping[str, np.ndarray], path: Path) -> None:
    """A model's test predictions on one shape (:func:`toolpath.models.training.replicates.saved_predictions`)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)


def load_predictions(path: Path, model: str) -> dict[str, np.ndarray]:
    return load_arrays(path, ["predicted", "degenerate"], "test-predictions", f"train@{model}")


# ---- checkpoints ---------------------------------------------------------------------------------
def save_checkpoint(checkpoint: dict, path: Path) -> None:
    import torch
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(checkpoint, path)


def load_checkpoint(path: Path, producer: str = "train") -> dict:
    """A classifier checkpoint (weights only: a checkpoint cannot run code when loaded)."""
    import pickle

    import torch

    if not path.is_file():
        raise ArtifactError(path, "model file not found", producer)
    try:
        checkpoint = torch.load(path, weights_only=True)
    except (RuntimeError, EOFError, OSError, ValueError, pickle.UnpicklingError) as exc:
        # torch's first line for a non-checkpoint is a paragraph about weights_only; say what it means
        reason = "not a torch checkpoint of plain tensors" if "Weights only load failed" in str(exc) else \
            (str(exc).splitlines() or [type(exc).__name__])[0][:160]
        raise ArtifactError(path, f"not a readable model file ({reason})", producer) from None
    if not isinstance(checkpoint, dict) or "network" not in checkpoint:
        raise ArtifactError(path, "malformed model file, no network config", producer)
    return checkpoint


def load_classifier(path: Path, producer: str = "train") -> Any:
    """The fitted classifier of a checkpoint; weights that do not fit the network they name (a file
    from another version, a damaged one) stop with one line instead of a traceback."""
    from toolpath.models.training.classifier import from_checkpoint

    checkpoint = load_checkpoint(path, producer)
    try:
        return from_checkpoint(checkpoint)
    except (KeyError, TypeError, ValueError, RuntimeError, AttributeError) as exc:
        reason = (str(exc).splitlines() or [type(exc).__name__])[0][:200]
        raise ArtifactError(path, f"malformed model file ({type(exc).__name__}: {reason})", producer) from None


def load_int8(path: Path, producer: str = "qat") -> Any:
    """An INT8 ``.pt2`` program (:func:`toolpath.inference.qat.load`), in eval mode; any failure to
    load it is the file's problem, said in one line."""
    from toolpath.inference import qat

    if not path.is_file():
        raise ArtifactError(path, "INT8 model file not found", producer)
    try:
        model = qat.load(path)
    except Exception as exc:  # noqa: BLE001 - torch.export raises many kinds for a damaged archive
        reason = (str(exc).splitlines() or [type(exc).__name__])[0][:200]
        raise ArtifactError(path, f"not a readable INT8 model file ({type(exc).__name__}: {reason})",
                            producer) from None
    model.eval()  # the exported-graph eval() switches dropout in place and returns None
    return model


CURVE_COLUMNS = ("epoch", "lr", "train_loss", "train_accuracy", "val_loss", "val_accuracy")


def write_curves(history: Iterable[Any], path: Path) -> None:
    """Per-epoch training records as the DVC plot's CSV (Figs. 6-7), fixed precision per column."""
    write_rows(({"epoch": r.epoch, "lr": f"{r.lr:.6g}", **{k: f"{getattr(r, k):.6f}" for k in CURVE_COLUMNS[2:]}}
                for r in history), CURVE_COLUMNS, path)


# ---- JSON and CSV --------------------------------------------------------------------------------
def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def write_json(data: Mapping, path: Path) -> None:
    """Deterministic JSON (sorted keys, fixed indentation, NaN/inf as null)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_finite(dict(data)), indent=2, sort_keys=True) + "\n", encoding="utf-8")


def read_json(path: Path, producer: str) -> dict:
    if not path.is_file():
        raise ArtifactError(path, "metrics file not found", producer)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (ValueError, UnicodeDecodeError) as exc:
        raise ArtifactError(path, f"not a readable JSON file ({exc})", producer) from None


def write_rows(rows: Iterable[Mapping], columns: Iterable[str], path: Path) -> None:
    """One CSV row per mapping, ``columns`` in order; floats to 6 significant digits."""
    columns = list(columns)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(columns)
        for r in rows:
            writer.writerow([f"{r[k]:.6g}" if isinstance(r[k], float) else r[k] for k in columns])


def read_rows(path: Path, producer: str, required: Iterable[str] = ()) -> list[dict[str, str]]:
    """The rows of a CSV table; a missing file, undecodable bytes or a missing column is one line."""
    if not path.is_file():
        raise ArtifactError(path, "table not found", producer)
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            rows, columns = list(reader), reader.fieldnames or []
    except (UnicodeDecodeError, csv.Error) as exc:
        raise ArtifactError(path, f"not a readable CSV table ({exc})", producer) from None
    if missing := [c for c in required if c not in columns]:
        raise ArtifactError(path, f"malformed table, missing column {', '.join(missing)}", producer)
    return rows
