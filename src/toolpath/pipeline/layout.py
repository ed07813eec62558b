"""Where every artefact lives, below the roots of ``conf/paths`` (re-exported by :mod:`toolpath.pipeline.artifacts`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class Layout:
    """Where every artefact lives, from the roots of ``conf/paths``."""

    gcode: Path
    windows: Path
    metrics: Path
    models: Path
    plots: Path
    timing: Path
    corpus: Path
    smoothed: Path
    report: Path
    sheets: Path
    sequence: Path
    corner: Path

    @classmethod
    def from_config(cls, paths: Mapping[str, Any]) -> Layout:
        return cls(**{f.name: Path(str(paths[f.name])) for f in fields(cls)})

    # ---- per shape -------------------------------------------------------------------------
    def programs(self, shape: str) -> Path:
        return self.gcode / shape

    def windows_file(self, shape: str) -> Path:
        return self.windows / f"{shape}.npz"

    def label_metrics(self, shape: str) -> Path:
        return self.metrics / "label" / f"{shape}.json"

    # ---- per (shape, model): the train and qat stages are a matrix over models, each over every shape
    def fp32_dir(self, model: str) -> Path:
        return self.models / "fp32" / model

    def checkpoint(self, shape: str, model: str) -> Path:
        """An FP32 classifier trained on one shape (the train stage's)."""
        return self.fp32_dir(model) / f"{shape}.pt"

    def generalised(self, model: str) -> Path:
        """The FP32 classifier trained on every shape (generalise)."""
        return self.models / "all" / f"{model}.pt"

    def test_predictions(self, shape: str, model: str) -> Path:
        """Every replicate's predicted category per test window, and which replicates are degenerate."""
        return self.fp32_dir(model) / f"{shape}.test.npz"

    def int8_dir(self, model: str) -> Path:
        return self.models / "int8" / model

    def int8_model(self, shape: str, model: str) -> Path:
        return self.int8_dir(model) / f"{shape}.pt2"

    def int8_onnx(self, shape: str, model: str) -> Path:
        """The INT8 graph as ONNX (QDQ): what ONNX Runtime and OpenVINO run (:mod:`toolpath.inference.runtimes`)."""
        return self.int8_dir(model) / f"{shape}.onnx"

    def train_metrics(self, shape: str, model: str) -> Path:
        return self.metrics / "train" / model / f"{shape}.json"

    def train_curves(self, shape: str, model: str) -> Path:
        return self.plots / "train" / model / f"{shape}.csv"

    def train_timing(self, shape: str, model: str) -> Path:
        return self.timing / "train" / model / f"{shape}.json"

    def comparison(self, shape: str, kind: str) -> Path:
        """The compare stage's figures of one shape: "paired" (MCRL against each model) or "logistic"."""
        return self.metrics / "compare" / shape / f"{kind}.json"

    def qat_metrics(self, model: str) -> Path:
        """One model's QAT record, keyed by shape."""
        return self.metrics / "qat" / f"{model}.json"

    def qat_timing(self, model: str) -> Path:
        return self.timing / "qat" / f"{model}.json"

    # ---- per shape ---------------------------------------------------------------------------
    def smoothed_file(self, shape: str) -> Path:
        return self.smoothed / f"{shape}.npz"

    def optimize_rows(self, shape: str) -> Path:
        return self.metrics / "optimize" / f"{shape}.csv"

    def optimize_summary(self, shape: str) -> Path:
        return self.metrics / "optimize" / f"{shape}.json"

    def optimize_timing(self, shape: str) -> Path:
        return self.timing / "optimize" / f"{shape}.json"

    def optimize_curves(self, shape: str) -> Path:
        return self.plots / "optimize" / f"{shape}.csv"

    def feedrate_rows(self, shape: str) -> Path:
        return self.metrics / "feedrate" / f"{shape}.csv"

    def feedrate_summary(self, shape: str) -> Path:
        return self.metrics / "feedrate" / f"{shape}.json"

    # ---- whole pipeline --------------------------------------------------------------------
    @property
    def generalise_metrics(self) -> Path:
        return self.metrics / "generalise.json"

    @property
    def inference_metrics(self) -> Path:
        return self.metrics / "inference.json"

    @property
    def classify_metrics(self) -> Path:
        """Table 5: one drawn test window per category and every model's prediction (classify stage)."""
        return self.metrics / "classify.json"

    @property
    def sequence_metrics(self) -> Path:
        return self.metrics / "sequence.json"

    @property
    def sequence_timing(self) -> Path:
        return self.timing / "sequence.json"

    def sheet(self, count: int) -> Path:
        return self.sheets / f"sheet_{count}.json"

    def sheet_plans(self, count: int) -> Path:
        return self.sequence / f"sheet_{count}.json"

    def sheet_program(self, count: int) -> Path:
        return self.sequence / f"sheet_{count}.nc"

    @property
    def corner_metrics(self) -> Path:
        return self.metrics / "corner.json"

    @property
    def corner_rows(self) -> Path:
        return self.metrics / "corner_corners.csv"

    @property
    def corner_timing(self) -> Path:
        return self.timing / "corner.json"

    @property
    def corner_curves(self) -> Path:
        return self.plots / "corner" / "training.csv"

    @property
    def surrogates(self) -> Path:
        return self.corner / "surrogates.pt"

    @property
    def corner_profiles(self) -> Path:
        return self.corner / "profiles.npz"
