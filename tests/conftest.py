"""Shared fixtures: the real G-code corpus, an isolated MLflow store, the repository root."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CORPUS = REPO.parent / "shared" / "gcode-corpus"


@pytest.fixture
def corpus() -> Path:
    if not CORPUS.is_dir():
        pytest.skip(f"real G-code corpus not found at {CORPUS} (shared/ is absent on this machine)")
    return CORPUS


@pytest.fixture
def mlflow_store(tmp_path, monkeypatch) -> str:
    uri = f"sqlite:///{tmp_path}/mlflow.db"
    monkeypatch.setenv("MLFLOW_TRACKING_URI", uri)
    monkeypatch.setenv("DVC_ROOT", str(tmp_path))
    return uri


def write_windows(path: Path, windows, label, split, program=None) -> Path:
    """A windows file with the label stage's whole schema (the fields a test does not care about zero)."""
    import numpy as np

    from toolpath.artifacts import WindowSet, save_windows

    n = len(windows)
    save_windows(WindowSet(windows=np.asarray(windows, np.float32), origin=np.zeros((n, 2)),
                           local_curvature=np.zeros(n), label=np.asarray(label, np.int8),
                           program=np.zeros(n, np.int32) if program is None else np.asarray(program, np.int32),
                           first_line=np.zeros(n, np.int32), split=np.asarray(split, np.int8),
                           program_files=np.array(["p.nc"])), path)
    return path
