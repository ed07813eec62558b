"""Shared fixtures: the real G-code corpus, an isolated MLflow store, the repository root, an easy split
and an MLP trained on it."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
CORPUS = REPO.parent / "shared" / "gcode-corpus"


@pytest.fixture
def corpus() -> Path:
    if not CORPUS.is_dir():
        pytest.skip(f"real G-code corpus not found at {CORPUS} (shared/ is absent on this machine)")
    return CORPUS


@pytest.fixture(scope="session")
def mlflow_template(tmp_path_factory) -> Path:
    """An empty MLflow SQLite store, made once per test process: MLflow makes a new store by running its
    schema migrations (3-5 s each time), and a copy of this file is the store it would make (see
    :func:`copy_store`); tests/test_tracking.py still makes new ones."""
    import mlflow

    path = tmp_path_factory.mktemp("mlflow-template") / "mlflow.db"
    mlflow.MlflowClient(f"sqlite:///{path}").search_experiments()
    return path


def copy_store(template: Path, path: Path) -> str:
    """The empty store at ``path`` (its URI), as MLflow would make it there: the template's tables, and its
    default experiment's artefacts beside the file instead of beside the template."""
    import sqlite3
    from contextlib import closing

    shutil.copyfile(template, path)
    with closing(sqlite3.connect(path)) as db, db:
        db.execute("UPDATE experiments SET artifact_location = ? WHERE experiment_id = 0",
                   (str(path.parent / "mlruns" / "0"),))
    return f"sqlite:///{path}"


@pytest.fixture
def mlflow_store(tmp_path, monkeypatch, mlflow_template) -> str:
    uri = copy_store(mlflow_template, tmp_path / "mlflow.db")
    monkeypatch.setenv("MLFLOW_TRACKING_URI", uri)
    monkeypatch.setenv("DVC_ROOT", str(tmp_path))
    return uri


def write_windows(path: Path, windows, label, split, program=None) -> Path:
    """A windows file with the generate stage's whole schema (the fields a test does not care about zero)."""
    import numpy as np

    from toolpath.pipeline.artifacts import WindowSet, save_windows

    n = len(windows)
    save_windows(WindowSet(windows=np.asarray(windows, np.float32), origin=np.zeros((n, 2)),
                           local_curvature=np.zeros(n), label=np.asarray(label, np.int8),
                           program=np.zeros(n, np.int32) if program is None else np.asarray(program, np.int32),
                           first_line=np.zeros(n, np.int32), split=np.asarray(split, np.int8),
                           program_files=np.array(["p.nc"])), path)
    return path


def easy_split(n=192, seed=0):
    """Straight lines (class index 0) against zig-zags (class index 3), at random scales and slopes."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 10, 50)
    X, y = [], []
    for k in range(n):
        rough = k % 2
        pts = np.column_stack([t, (1.5 * (np.arange(50) % 2) if rough else np.zeros(50))])
        angle = rng.uniform(-0.3, 0.3)
        rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        X.append(rng.uniform(0.5, 2) * pts @ rot.T)
        y.append(3 * rough)
    return np.asarray(X, dtype=np.float32), np.asarray(y)


@pytest.fixture(scope="module")
def trained_mlp():
    """An MLP trained on :func:`easy_split` (QAT and runtime tests start from it)."""
    from toolpath.models.training import TorchClassifier

    X, y = easy_split()
    settings = {"lr": 3e-3, "epochs": 15, "batch_size": 32, "decay_steps": 1000, "seed": 1}
    clf = TorchClassifier({"_target_": "toolpath.models.MLP"}, settings).fit(X, y + 1)
    return clf, X, y


LONG_GROUPS = ("pipeline", "queue", "sweep")  # the end-to-end runs and the sweeps: minutes each


def pytest_collection_modifyitems(config, items):
    """Run the long groups first: `make test`'s two workers each start with one (the second takes the
    sweeps after the queue) and share the unit tests after, instead of one worker reaching a several-minute
    group last."""
    def rank(item):
        marker = item.get_closest_marker("xdist_group")
        group = (marker.args[0] if marker and marker.args else marker.kwargs.get("name")) if marker else None
        return LONG_GROUPS.index(group) if group in LONG_GROUPS else len(LONG_GROUPS)

    items.sort(key=rank)  # stable: every other test keeps its order


@pytest.fixture
def warm_server(tmp_path):
    """A warm server (toolpath.pipeline.warm) without the preload, at the socket path it yields."""
    import subprocess
    import sys
    import time

    from toolpath.pipeline import warm

    path = tmp_path / "warm.sock"
    process = subprocess.Popen([sys.executable, "-m", warm.MODULE, "--serve", str(path), "--cold"],
                               start_new_session=True, stdout=subprocess.DEVNULL)
    deadline = time.monotonic() + 30
    while not path.exists():
        assert process.poll() is None and time.monotonic() < deadline, "the warm server did not start"
        time.sleep(0.02)
    yield path
    process.terminate()
    process.wait(10)
