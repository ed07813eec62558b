"""MLflow wiring: one experiment, one parent run per pipeline run, one child run per stage item.

The store is SQLite in the repository root (``sqlite:///$DVC_ROOT/mlflow.db``) unless ``MLFLOW_TRACKING_URI``
is set; artefacts go to ``$DVC_ROOT/mlruns``.  The parent run is named after the DVC experiment
(``DVC_EXP_NAME``) or ``repro-<git sha>``; one parent per ``dvc`` process the stages run under (``dvc repro``,
``dvc exp run``: its pid and start time), so every stage of one invocation lands under it.

Runs span their work: the parent starts when that ``dvc`` process started and ends when its last
stage ends; a stage's run starts when its process started; a model's spans its training.  The parent
carries the composed configuration (``params.yaml``, flattened, and the file) and a description saying
how to reproduce it.

Concurrent writers (``dvc queue start -j N``, sweep workers) share the one SQLite file: each connection
waits up to :data:`SQLITE_BUSY_SECONDS` for the write lock, a file lock serialises opening (and migrating)
the store, and the creations that can still race are retried.  One store, so ``mlflow ui`` sees every run
at once; past a few writers, use PostgreSQL (see the README).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import subprocess
import time
import warnings
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any, TypeVar

from toolpath.pipeline.stage_times import end_line, started_at
from toolpath.pipeline.warm import STAGE_PID_ENV

EXPERIMENT = "cnc-curvature"
EXPERIMENT_TAGS = {  # MLflow 3's UI opens a "custom model development" experiment on its runs table
    "mlflow.experimentKind": "custom_model_development",
    "mlflow.note.content": "toolpath-lab: CNC toolpath roughness recognition (MCRL and baselines, Tables 2-5), "
                           "window smoothing (Table 6), NURBS corners and feedrate. One parent run per "
                           "`dvc repro` / `dvc exp run`, one child run per stage, one nested run per model."}
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
        raise TrackingStoreError(f"MLflow store {uri}: cannot be opened ({reason}); set MLFLOW_TRACKING_URI") from None


def experiment_id(client: Any, name: str = EXPERIMENT) -> str:
    """The id of experiment ``name``, created (artefacts under ``mlruns/``) when missing, under the
    store's init lock (this may be the first use of a new store)."""
    def get_or_create() -> str:
        found = client.get_experiment_by_name(name)
        if found is None:
            return client.create_experiment(name, artifact_location=(repo_root() / "mlruns").as_uri(),
                                            tags=EXPERIMENT_TAGS)
        for key, value in EXPERIMENT_TAGS.items():  # a store made by an earlier version
            if found.tags.get(key) != value:
                client.set_experiment_tag(found.experiment_id, key, value)
        return found.experiment_id

    with sqlite_file_lock(str(client.tracking_uri)), _store_errors(str(client.tracking_uri)):
        return with_retry(get_or_create)


def client(uri: str | None = None) -> Any:
    """An MLflow client of ``uri`` (default :func:`tracking_uri`), opened (a new store migrated) under its lock."""
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


def dvc_invocation() -> tuple[str, int]:
    """(pid-start, start in ms) of the ``dvc`` process this stage runs under (else of this stage's process)."""
    import psutil

    found = me = psutil.Process(stage_pid())
    for process in me.parents():
        with contextlib.suppress(psutil.Error):
            if any(Path(word).name == "dvc" for word in process.cmdline()[:3]):  # dvc, python .../dvc, python -m dvc
                found = process
                break
    return f"{found.pid}-{int(found.create_time())}", int(1000 * (started_at(found.pid) or found.create_time()))


def stage_pid() -> int:
    """The stage's process as DVC started it: this one, or the one that handed it to a warm runner (which it awaits)."""
    return int(os.environ.get(STAGE_PID_ENV) or os.getpid())


def process_start_ms() -> int:
    """When the stage's process started (ms since the epoch): a stage's run starts there, not at its first log."""
    import psutil

    return int(1000 * (started_at(stage_pid()) or psutil.Process(stage_pid()).create_time()))


START_DRIFT_MS = 120_000  # a process's start as psutil reads it drifted 8 s over one 35-minute `dvc repro` here


def _parent_run_id(client: Any, experiment_id: str, key: str) -> str:
    """The parent of this ``dvc`` process (its pid, a start within :data:`START_DRIFT_MS`), else a new one."""
    invocation, started = dvc_invocation()
    pid = invocation.split("-")[0]
    query = f"tags.pipeline_key = '{key}' and tags.pipeline_role = 'parent' and tags.dvc_pid = '{pid}'"
    for found in client.search_runs([experiment_id], filter_string=query, max_results=50):
        if abs(found.info.start_time - started) <= START_DRIFT_MS:
            return found.info.run_id
    tags = {"pipeline_key": key, "pipeline_role": "parent", "git_commit": git_commit(), "invocation": invocation,
            "dvc_pid": pid, "mlflow.note.content": _description(key)}
    run = client.create_run(experiment_id, start_time=started, run_name=key, tags=tags)
    _log_configuration(client, run.info.run_id)
    return run.info.run_id


def _description(key: str) -> str:
    params = repo_root() / "params.yaml"
    profile = "?"
    with contextlib.suppress(OSError, ValueError):
        import yaml

        profile = (yaml.safe_load(params.read_text(encoding="utf-8")) or {}).get("profile", "?")
    reproduce = (f"`git checkout {git_commit()} && make repro`" if profile == "default" else
                 f"`git checkout {git_commit()} && make install && .venv/bin/python -m toolpath.pipeline.config "
                 f"+experiment={profile} && .venv/bin/dvc repro` (`make repro` composes the default profile)")
    return (f"Pipeline run `{key}`: profile `{profile}`, commit `{git_commit()}`. Reproduce: {reproduce}. Its "
            "configuration is this run's parameters and `params.yaml`; each stage is a child run, each trained "
            "network a nested run with its MLflow model.")


def _log_configuration(client: Any, run_id: str) -> None:
    """The composed configuration on the parent: ``params.yaml`` flattened (MLflow takes 100 a batch,
    values up to 6000 characters) and the file itself."""
    from mlflow.entities import Param

    params = repo_root() / "params.yaml"
    if not params.is_file():
        return
    import yaml

    from toolpath.pipeline.config import flat

    values = flat(yaml.safe_load(params.read_text(encoding="utf-8")) or {})
    items = [Param(k[:250], str(v)[:6000]) for k, v in sorted(values.items())]
    for start in range(0, len(items), 100):
        with_retry(lambda batch=items[start:start + 100]: client.log_batch(run_id, params=batch))
    with_retry(lambda: client.log_artifact(run_id, str(params)))


def _close_parent(client: Any, parent: str, failed: bool) -> None:
    """Each stage's end is the parent's end so far: after the last stage, the parent spans the pipeline."""
    with_retry(lambda: client.set_terminated(parent, "FAILED" if failed else "FINISHED", int(time.time() * 1000)))


def log_to_parent(metrics: Mapping[str, float], tags: Mapping[str, str]) -> str:
    """Put the pipeline's headline figures and tags on its parent run (so `mlflow ui` answers "how did
    this run do" on the parent's page); returns the parent's id."""
    store, parent = client(), parent_run_id()
    for key, value in metrics.items():
        with_retry(lambda k=key, v=value: store.log_metric(parent, k, float(v)))
    for key, value in tags.items():
        with_retry(lambda k=key, v=value: store.set_tag(parent, k, v))
    return parent


SYSTEM_METRICS_SECONDS = 5.0  # a stage's CPU / memory sampled this often (MLflow's system metrics; needs psutil)


@contextlib.contextmanager
def stage_run(stage: str, params: Mapping[str, Any] | None = None, **tags: str) -> Iterator[Any]:
    """Open the child run of ``stage`` (e.g. ``generate@gear``) under the pipeline's parent run, started
    when this process started; on exit the parent's end moves to now and the process prints the line
    :mod:`~toolpath.pipeline.stage_times` ends the stage at (the two spans agree).  The run (and the
    parent) is marked FAILED if the body raises.  Params are logged once, as given."""
    import mlflow

    mlflow.set_tracking_uri(tracking_uri())
    store = client()
    experiment = experiment_id(store)
    with sqlite_file_lock(tracking_uri()):  # two stages of one invocation starting at once share a parent
        parent = with_retry(lambda: _parent_run_id(store, experiment, pipeline_key()))
    name = os.environ.get("DVC_STAGE") or stage
    run_tags = {"stage": stage, "git_commit": git_commit(), "pipeline_key": pipeline_key(), **tags,
                "start": "warm" if os.environ.get(STAGE_PID_ENV) else "cold",
                "mlflow.parentRunId": parent}
    created = with_retry(lambda: store.create_run(experiment, start_time=process_start_ms(), run_name=name,
                                                  tags=run_tags))
    failed = True
    try:
        mlflow.set_system_metrics_sampling_interval(SYSTEM_METRICS_SECONDS)
        with mlflow.start_run(run_id=created.info.run_id, log_system_metrics=True) as run:  # CPU, memory, disk
            if params:
                mlflow.log_params({k: str(v)[:6000] for k, v in params.items()})
            yield run
        failed = False
    finally:
        _close_parent(store, parent, failed)
        print(end_line(name, failed, time.time() - process_start_ms() / 1000, created.info.run_id), flush=True)


def parent_run_id() -> str:
    """The id of this invocation's parent run."""
    store = client()
    return with_retry(lambda: _parent_run_id(store, experiment_id(store), pipeline_key()))


def log_model_run(name: str, tags: Mapping[str, str], params: Mapping[str, Any], curves: list,
                  metrics: Mapping[str, float], artifacts: Mapping[str, Any], span: tuple[float, float] | None = None,
                  network: Any = None, example: Any = None) -> str | None:
    """One model's run nested in the active stage run, spanning ``span`` (start, end: epoch seconds) when
    given: its per-epoch curves (each record's fields at step = epoch, timed across the span), final
    metrics (step 0), params, dicts logged as JSON and files as artefacts (``name.json`` -> a dict,
    anything else -> a path), and ``network`` (a torch module) as an MLflow PyTorch model with the
    signature of ``example`` (a window batch).  Returns the model's URI (None without a network)."""
    import mlflow
    from mlflow.entities import Metric, Param

    stage = mlflow.active_run()
    store = mlflow.MlflowClient()
    inherited = {k: v for k, v in stage.data.tags.items() if not k.startswith("mlflow.")}
    started, ended = span or (time.time(), time.time())  # in ms rounded outwards: a rule's sub-ms fit lasts 1 ms
    started, ended = math.floor(started * 1000) / 1000, math.ceil(ended * 1000) / 1000
    tags = {**inherited, **tags, "mlflow.parentRunId": stage.info.run_id}
    run = with_retry(lambda: store.create_run(stage.info.experiment_id, round(started * 1000), tags, name))
    run_id, epochs = run.info.run_id, max(len(curves), 1)
    values = [Metric(k, float(v), int(1000 * (started + (ended - started) * record.epoch / epochs)), record.epoch)
              for record in curves for k, v in vars(record).items() if k != "epoch"]
    values += [Metric(k, float(v), int(ended * 1000), 0) for k, v in metrics.items()]
    for start in range(0, max(len(values), 1), 1000):  # MLflow's batch limits: 1000 metrics, 100 params
        store.log_batch(run_id, metrics=values[start:start + 1000])
    items = [Param(k, str(v)[:6000]) for k, v in params.items()]
    for start in range(0, len(items), 100):
        store.log_batch(run_id, params=items[start:start + 100])
    for file_name, item in artifacts.items():
        if file_name.endswith(".json") and isinstance(item, dict):
            store.log_dict(run_id, item, file_name)
        else:
            store.log_artifact(run_id, str(item))
    uri = None
    if network is not None:
        uri = _log_network(run_id, network, example)
    store.set_terminated(run_id, "FINISHED", round(ended * 1000))
    return uri


def _log_network(run_id: str, network: Any, example: Any) -> str:
    """``network`` as an MLflow PyTorch model of ``run_id``: input a batch of 50-point windows (N, 50, 2)
    float32 in mm relative to the first point, output the four Table 1 logits."""
    import mlflow
    import numpy as np
    import torch
    from mlflow.models import infer_signature

    network.eval()
    with torch.no_grad():
        logits = network(torch.as_tensor(example)).numpy()
    with mlflow.start_run(run_id=run_id, nested=True), warnings.catch_warnings():
        # MLflow's own GenAI types warn about their type hints on first import: nothing of ours
        warnings.filterwarnings("ignore", message=".*inferred as AnyType.*")
        # torch.export of nn.RNN / nn.LSTM notes their _flat_weights were assigned during tracing: the saved
        # program's logits equal the network's (tests/test_pipeline.py loads it back), so it is noise to a user
        warnings.filterwarnings("ignore", message=r"The tensor attributes .*_flat_weights.* were assigned")
        info = mlflow.pytorch.log_model(network, name="model", signature=infer_signature(example, logits),
                                        input_example=np.asarray(example),
                                        pip_requirements=[f"torch>={torch.__version__.split('+')[0]}", "numpy"],
                                        # MLflow would load the saved program back and run the example: a
                                        # quarter of the log's time for a network with recurrences, paid per
                                        # model and shape; tests/test_pipeline.py loads a registered one and runs it
                                        validate_serving_input=False)
    return info.model_uri


def log_onnx_model(name: str, path: Path, tags: Mapping[str, str]) -> str:
    """An ONNX file (the INT8 export the runtimes run) as an MLflow ONNX model of the active run."""
    import mlflow
    import onnx

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*inferred as AnyType.*")
        info = mlflow.onnx.log_model(onnx.load(str(path)), name=name, tags=dict(tags), pip_requirements=["onnxruntime"])
    return info.model_uri


def record_up_to_date(stages: set[str]) -> dict[str, str]:
    """Tag the parent with each stage of ``stages`` (``dvc.yaml`` names) this invocation did not run:
    ``up_to_date.<run name>`` = the run that produced its outputs.  Returns those tags."""
    store = client()
    experiment = experiment_id(store)
    parent = with_retry(lambda: _parent_run_id(store, experiment, pipeline_key()))
    latest: dict[str, Any] = {}
    ran_now: set[str] = set()
    for run in store.search_runs([experiment], filter_string="attributes.status = 'FINISHED'",
                                 order_by=["attributes.start_time DESC"], max_results=5000):
        name, tags = run.info.run_name, run.data.tags
        if "stage" in tags and "model" not in tags and name.split("@")[0] in stages:
            if tags.get("mlflow.parentRunId") == parent:
                ran_now.add(name)  # runs of one process share a start time: order alone cannot tell
            latest.setdefault(name, run)
    # MLflow keys take no "@": generate@gear is tagged up_to_date.generate.gear
    skipped = {f"up_to_date.{name.replace('@', '.')}": f"up to date, produced by run {run.info.run_id} "
               f"({run.data.tags.get('pipeline_key', '?')})"
               for name, run in sorted(latest.items()) if name not in ran_now}
    for key, value in skipped.items():
        with_retry(lambda k=key, v=value: store.set_tag(parent, k, v))
    return skipped


def log_to_parent_artifacts(paths: Mapping[str, Path]) -> None:
    """Files (``{artefact folder: path}``, '' for the root) and folders on the parent run."""
    store, parent = client(), parent_run_id()
    for folder, path in paths.items():
        if path.is_dir():
            store.log_artifacts(parent, str(path), folder or None)
        elif path.is_file():
            store.log_artifact(parent, str(path), folder or None)
