"""MLflow wiring: one experiment, one parent run per pipeline run, one child run per stage item.

The store is SQLite in the repository root (``sqlite:///$DVC_ROOT/mlflow.db``) unless
``MLFLOW_TRACKING_URI`` is set; artefacts go to ``$DVC_ROOT/mlruns``.  The parent run is named
after the DVC experiment (``DVC_EXP_NAME``) or ``repro-<git sha>`` and found again by its
``pipeline_key`` tag, so every stage of one pipeline run lands under it.

Concurrent writers (``dvc queue start -j N``, sweep workers) share the one SQLite file: every
connection waits up to :data:`SQLITE_BUSY_SECONDS` for the write lock (SQLite's busy timeout), a
file lock serialises opening the store (a new store is migrated on first use), and the creations
that can still race (the experiment, a parent run) are retried.  We keep
one store rather than a store per worker merged afterwards: MLflow writes are a handful of short
transactions per stage, so waiting costs little, and ``mlflow ui`` sees every run at once.  Past a
few writers, point ``MLFLOW_TRACKING_URI`` at PostgreSQL (see the README).
"""

from __future__ import annotations

import contextlib
import logging
import os
import subprocess
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, TypeVar

EXPERIMENT = "cnc-curvature"
SQLITE_BUSY_SECONDS = 60
T = TypeVar("T")
log = logging.getLogger(__name__)


def repo_root() -> Path:
    return Path(os.environ.get("DVC_ROOT") or Path.cwd()).resolve()


def tracking_uri() -> str:
    return os.environ.get("MLFLOW_TRACKING_URI") or \
        f"sqlite:///{repo_root() / 'mlflow.db'}?timeout={SQLITE_BUSY_SECONDS}"


def _transient(exc: BaseException) -> bool:
    text = str(exc).lower()
    # the last two: another process is creating or migrating a new store's tables at the same moment
    return any(s in text for s in ("database is locked", "unique constraint", "already exists", "duplicate key",
                                   "alembic_version", "migration"))


def with_retry(action: Callable[[], T], attempts: int = 8) -> T:
    """``action()``, again after a short back-off when it lost a race with another writer."""
    for attempt in range(attempts):
        try:
            return action()
        except Exception as exc:
            if attempt == attempts - 1 or not _transient(exc):
                raise
            log.info("tracking store busy (%s); retrying", exc)
            time.sleep(0.2 * 2 ** attempt)
    raise AssertionError("unreachable")


@contextlib.contextmanager
def sqlite_file_lock(uri: str) -> Iterator[None]:
    """Hold ``<store>.lock`` (an exclusive file lock) for a SQLite URI; other URIs pass through.  MLflow
    opens its store under it: a new store is created by running its migrations, and two processes
    migrating one file at once corrupt each other's steps.  The sweep claims worker seeds under it."""
    prefix = "sqlite:///"
    if not uri.startswith(prefix):
        yield
        return
    import fcntl

    lock = Path(uri[len(prefix):].split("?", 1)[0] + ".lock")
    lock.parent.mkdir(parents=True, exist_ok=True)
    with lock.open("a") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


class TrackingStoreError(SystemExit):
    """The tracking store cannot be opened (a corrupt ``mlflow.db``, an unreachable server): one line."""


@contextlib.contextmanager
def _store_errors(uri: str) -> Iterator[None]:
    """Turn a store that cannot be opened into one line naming it and what to do."""
    try:
        yield
    except TrackingStoreError:
        raise
    except Exception as exc:
        reason = (str(exc).splitlines() or [type(exc).__name__])[0][:200]
        prefix = "sqlite:///"
        if uri.startswith(prefix):
            path = uri[len(prefix):].split("?", 1)[0]
            raise TrackingStoreError(f"{path}: not a usable MLflow store ({reason}); move it aside "
                                     f"(mv {path} {path}.bad) to start a new one, or set MLFLOW_TRACKING_URI") from None
        raise TrackingStoreError(f"MLflow store {uri}: cannot be opened ({reason}); check MLFLOW_TRACKING_URI") \
            from None


def experiment_id(client: Any, name: str = EXPERIMENT) -> str:
    """The id of experiment ``name``, created (artefacts under ``mlruns/``) when missing.

    Runs under the store's init lock, in case this is the first use of a new store."""
    def get_or_create() -> str:
        found = client.get_experiment_by_name(name)
        return found.experiment_id if found else \
            client.create_experiment(name, artifact_location=(repo_root() / "mlruns").as_uri())

    with sqlite_file_lock(str(client.tracking_uri)), _store_errors(str(client.tracking_uri)):
        return with_retry(get_or_create)


def client(uri: str | None = None) -> Any:
    """An MLflow client of ``uri`` (default :func:`tracking_uri`); creating it opens (and, for a new
    store, migrates) the store, so it runs under the store's init lock."""
    import mlflow

    uri = uri or tracking_uri()
    with sqlite_file_lock(uri), _store_errors(uri):
        found = with_retry(lambda: mlflow.MlflowClient(tracking_uri=uri))
        found.search_experiments(max_results=1)  # MlflowClient opens lazily: a corrupt file fails here
        return found


def git_commit(root: Path | None = None) -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=root or repo_root(),
                             capture_output=True, text=True, check=True)
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "nogit"


def pipeline_key() -> str:
    return os.environ.get("DVC_EXP_NAME") or f"repro-{git_commit()}"


def _parent_run_id(client: Any, experiment_id: str, key: str) -> str:
    query = f"tags.pipeline_key = '{key}' and tags.pipeline_role = 'parent'"
    found = client.search_runs([experiment_id], filter_string=query, max_results=1)
    if found:
        return found[0].info.run_id
    tags = {"pipeline_key": key, "pipeline_role": "parent", "git_commit": git_commit()}
    run = client.create_run(experiment_id, run_name=key, tags=tags)
    client.set_terminated(run.info.run_id)
    return run.info.run_id


def log_to_parent(metrics: Mapping[str, float], tags: Mapping[str, str]) -> str:
    """Put the pipeline's headline figures and tags on its parent run (so `mlflow ui` answers "how did
    this run do" on the parent's page); returns the parent's id."""
    store = client()
    experiment = experiment_id(store)
    parent = with_retry(lambda: _parent_run_id(store, experiment, pipeline_key()))
    for key, value in metrics.items():
        with_retry(lambda k=key, v=value: store.log_metric(parent, k, float(v)))
    for key, value in tags.items():
        with_retry(lambda k=key, v=value: store.set_tag(parent, k, v))
    return parent


@contextlib.contextmanager
def stage_run(stage: str, params: Mapping[str, Any] | None = None, **tags: str) -> Iterator[Any]:
    """Open the child run of ``stage`` (e.g. ``label@gear``) under the pipeline's parent run.

    The run is marked FAILED if the body raises.  Params are logged once, as given.
    """
    import mlflow

    mlflow.set_tracking_uri(tracking_uri())
    store = client()
    experiment = experiment_id(store)
    parent = with_retry(lambda: _parent_run_id(store, experiment, pipeline_key()))
    name = os.environ.get("DVC_STAGE") or stage
    run_tags = {"stage": stage, "git_commit": git_commit(), "pipeline_key": pipeline_key(), **tags}
    with mlflow.start_run(experiment_id=experiment, run_name=name, parent_run_id=parent, tags=run_tags) as run:
        if params:
            mlflow.log_params({k: str(v)[:6000] for k, v in params.items()})
        yield run


def log_model_run(name: str, tags: Mapping[str, str], params: Mapping[str, Any], curves: list,
                  metrics: Mapping[str, float], artifacts: Mapping[str, Any]) -> None:
    """One model's run nested in the active stage run: its per-epoch curves (each record's fields at
    step = epoch), final metrics (step 0), params, dicts logged as JSON and files as artefacts (``name.json``
    -> a dict, anything else -> a path).  One batch for the values: the stage process shares the cores
    with the training workers."""
    import time

    import mlflow
    from mlflow.entities import Metric, Param

    stage = mlflow.active_run()
    inherited = {k: v for k, v in stage.data.tags.items() if not k.startswith("mlflow.")}
    with mlflow.start_run(run_name=name, nested=True, experiment_id=stage.info.experiment_id,
                          tags={**inherited, **tags}):
        now = int(time.time() * 1000)
        values = [Metric(k, float(v), now, record.epoch) for record in curves
                  for k, v in vars(record).items() if k != "epoch"]
        values += [Metric(k, float(v), now, 0) for k, v in metrics.items()]
        mlflow.MlflowClient().log_batch(mlflow.active_run().info.run_id, metrics=values,
                                        params=[Param(k, str(v)[:6000]) for k, v in params.items()])
        for file_name, item in artifacts.items():
            if file_name.endswith(".json") and isinstance(item, dict):
                mlflow.log_dict(item, file_name)
            else:
                mlflow.log_artifact(str(item))
