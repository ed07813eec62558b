"""The Optuna study behind a sweep: its storage, its MLflow parent run and the workers that run trials.

Several processes (here, or on other machines sharing a PostgreSQL database) may work on one study:
the process that creates the study creates the MLflow parent run and records its id in the study;
the others wait for it.  Each worker runs an exact number of trials, so the trials add up; trial
numbers come from the storage, so none repeats.  A worker that dies leaves a RUNNING trial whose
heartbeat stops; Optuna marks it FAILED once the grace period passes, and it is not counted.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import optuna
from omegaconf import DictConfig, OmegaConf

from toolpath.pipeline import tracking
from toolpath.pipeline.config import compose_config as compose
from toolpath.pipeline.settings import layout
from toolpath.sweep.objective import average, load_splits, metric, train_and_score
from toolpath.sweep.space import Param, overrides, parse_space, suggest

SWEEP_EXPERIMENT = "cnc-curvature-sweeps"
PARENT_ATTR = "mlflow_parent_run_id"
PARENT_WAIT_SECONDS = 120
STORAGE_ENV = "TOOLPATH_SWEEP_STORAGE"
DEFAULT_STORAGE = "sqlite:///optuna.db"


@dataclass(frozen=True)
class SweepSpec:
    """Everything a worker process needs (picklable): the sweep section and the base overrides."""

    root: Path
    base_overrides: tuple[str, ...]
    study: str
    shape: str
    model: str
    objective: str
    n_trials: int
    workers: int
    seed: int
    storage: str
    tracking_uri: str
    heartbeat_seconds: int
    figures: Path
    summary: Path
    tuned_config: Path
    params: tuple[Param, ...]
    threads: int
    replicates: int = 1


def _absolute_sqlite(url: str, root: Path) -> str:
    """``sqlite:///optuna.db`` relative to the repository root, not to the current directory."""
    prefix = "sqlite:///"
    if url.startswith(prefix) and not url.startswith(prefix + "/"):
        return prefix + str(root / url[len(prefix):])
    return url


def outside_protocol(cfg: DictConfig, model: str) -> list[str]:
    """The override that takes the swept model out of ``train.protocol`` (whose settings would win over the
    keys the sweep samples); nothing when the protocol does not list it."""
    listed = list((cfg.train.get("protocol") or {}).get("models") or [])
    if model not in listed:
        return []
    return ["train.protocol.models=[" + ",".join(m for m in listed if m != model) + "]"]


def spec_from(cfg: DictConfig, root: Path, base_overrides: Sequence[str]) -> SweepSpec:
    """The sweep of a composed config (``+sweep=<name>``); a ValueError names a bad setting."""
    s = cfg.sweep
    if s.model not in cfg.models:
        raise ValueError(f"sweep.model: no model {s.model!r} in conf/model")
    if s.shape not in cfg.shapes:
        raise ValueError(f"sweep.shape: {s.shape!r} is not one of {list(cfg.shapes)}")
    if int(s.n_trials) < 1 or int(s.workers) < 1 or int(s.replicates) < 1:
        raise ValueError("sweep.n_trials, sweep.workers and sweep.replicates must be at least 1")
    params = parse_space(OmegaConf.to_container(s.space, resolve=True), s.shape)
    root = Path(root).resolve()
    return SweepSpec(
        root=root, base_overrides=(*base_overrides, *outside_protocol(cfg, str(s.model))), study=str(s.study),
        shape=str(s.shape),
        model=str(s.model), objective=str(s.objective), n_trials=int(s.n_trials), workers=int(s.workers),
        seed=int(s.seed),
        storage=_absolute_sqlite(str(s.storage or os.environ.get(STORAGE_ENV) or DEFAULT_STORAGE), root),
        tracking_uri=str(s.tracking_uri) if s.tracking_uri else tracking.tracking_uri(),
        heartbeat_seconds=int(s.heartbeat_seconds), figures=root / str(s.figures),
        summary=root / str(cfg.paths.report) / "sweep" / f"{s.study}.json", tuned_config=root / str(s.tuned_config),
        params=tuple(params), threads=max(1, int(cfg.train.common.threads) // int(s.workers)),
        replicates=int(s.replicates))


def open_storage(spec: SweepSpec) -> optuna.storages.RDBStorage:
    """The study's database; SQLite waits for its write lock instead of failing under parallel workers."""
    import warnings

    engine = {"connect_args": {"timeout": tracking.SQLITE_BUSY_SECONDS}} if spec.storage.startswith("sqlite") \
        else {"pool_pre_ping": True}
    with warnings.catch_warnings():  # the heartbeat is "experimental" in Optuna 5; it is what resuming needs
        warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
        # two processes creating the tables of a new database race; the loser retries and finds them
        try:
            return tracking.with_retry(lambda: optuna.storages.RDBStorage(
                spec.storage, engine_kwargs=engine, heartbeat_interval=max(1, spec.heartbeat_seconds // 4),
                grace_period=spec.heartbeat_seconds))
        except Exception as exc:  # a damaged file or an unreachable server: one line, not SQLAlchemy's trace
            reason = (str(exc).splitlines() or [type(exc).__name__])[0][:200]
            where = spec.storage.split("@")[-1]
            raise RuntimeError(f"{where}: not a usable Optuna study storage ({reason}); move the file aside or "
                               f"point {STORAGE_ENV} elsewhere") from None


def _sampler(spec: SweepSpec, worker: int) -> optuna.samplers.TPESampler:
    return optuna.samplers.TPESampler(seed=spec.seed + worker)


def claim_workers(spec: SweepSpec, study: optuna.Study, count: int) -> int:
    """The first of ``count`` worker indices (sampler seed: study seed + index) that no earlier launch
    on this study used.  The study records how many it has handed out (user attribute
    ``workers_claimed``), read and raised under the SQLite storage's file lock, so two sweeps launched
    separately on one study never sample with the same seed.  The first launch gets 0: one launch
    alone samples as it always did."""
    with _storage_lock(spec):
        claimed = int(study.user_attrs.get("workers_claimed", 0))
        study.set_user_attr("workers_claimed", claimed + count)
    return claimed


@contextlib.contextmanager
def _storage_lock(spec: SweepSpec) -> Iterator[None]:
    """An exclusive lock every process on the study's storage respects: the SQLite file's lock file,
    or a PostgreSQL advisory lock (sessions on other machines wait for it too)."""
    if not spec.storage.startswith("postgresql"):
        with tracking.sqlite_file_lock(spec.storage):
            yield
        return
    import sqlalchemy

    engine = sqlalchemy.create_engine(spec.storage, poolclass=sqlalchemy.pool.NullPool)
    key = int.from_bytes(hashlib.sha256(f"toolpath-sweep:{spec.study}".encode()).digest()[:7], "big")
    try:
        with engine.connect() as connection:
            connection.execute(sqlalchemy.text("SELECT pg_advisory_lock(:key)"), {"key": key})
            try:
                yield
            finally:
                connection.execute(sqlalchemy.text("SELECT pg_advisory_unlock(:key)"), {"key": key})
    finally:
        engine.dispose()


def mlflow_client(spec: SweepSpec) -> Any:
    return tracking.client(spec.tracking_uri)


_BASES: dict[tuple[str, tuple[str, ...], str], DictConfig] = {}


def base_config(root: Path, base_overrides: Sequence[str]) -> DictConfig:
    """``base_overrides`` composed on ``root/conf``, read-only: composed once per process and content of
    ``conf/`` (a launch reads its base configuration in four places, and a composition takes about a second;
    writing a tuned config into ``conf/`` makes the next call compose again)."""
    from toolpath.pipeline.config import CONF_DIR, _conf_digest

    key = (str(Path(root).resolve()), tuple(base_overrides), _conf_digest(Path(root) / CONF_DIR).hexdigest())
    if key not in _BASES:
        _BASES[key] = compose(root, base_overrides)
        OmegaConf.set_readonly(_BASES[key], True)
    return _BASES[key]


def default_params(spec: SweepSpec) -> dict[str, Any] | None:
    """The Optuna values of the configuration as composed (no sampled override), if inside the space."""
    base = base_config(spec.root, spec.base_overrides)
    def plain(key: str) -> Any:
        value = OmegaConf.select(base, key)
        return OmegaConf.to_container(value) if OmegaConf.is_config(value) else value

    values = {p.name: p.sampled(plain(p.key)) for p in spec.params}
    return None if any(v is None for v in values.values()) else values


def open_study(spec: SweepSpec, worker: int = 0, takes_enqueued: bool = True) -> optuna.Study:
    """Create the study (then its MLflow parent run and the default trial) or join it.  A joining
    process that must not take the enqueued trial (``takes_enqueued`` False) returns once it is taken."""
    storage = open_storage(spec)
    try:
        study = optuna.create_study(study_name=spec.study, storage=storage, direction="maximize",
                                    sampler=_sampler(spec, worker))
    except optuna.exceptions.DuplicatedStudyError:
        study = optuna.load_study(study_name=spec.study, storage=storage, sampler=_sampler(spec, worker))
        _wait_for_parent(study)
        if not takes_enqueued:
            _wait_until_enqueued_taken(study)
        return study
    for key, value in (("shape", spec.shape), ("model", spec.model), ("objective", spec.objective),
                       ("base_overrides", list(spec.base_overrides))):
        study.set_user_attr(key, value)
    defaults = default_params(spec)
    if defaults is not None:  # trial 0 is the configuration as composed: the baseline of the comparison
        study.enqueue_trial(defaults, user_attrs={"default_config": True})
    else:
        print(f"sweep {spec.study}: the composed configuration lies outside the search space; "
              "no default trial is enqueued")
    client = mlflow_client(spec)
    experiment = tracking.experiment_id(client, SWEEP_EXPERIMENT)
    tags = {"sweep_study": spec.study, "sweep_role": "parent", "git_commit": tracking.git_commit(spec.root),
            "shape": spec.shape, "model": spec.model}
    run = tracking.with_retry(lambda: client.create_run(experiment, run_name=spec.study, tags=tags))
    for key, value in {"n_trials": spec.n_trials, "workers": spec.workers, "seed": spec.seed,
                       "objective": spec.objective, "storage": spec.storage.split("@")[-1],
                       "base_overrides": " ".join(spec.base_overrides) or "(none)",
                       **{f"space.{p.name}": f"{p.key} {p.kind} {p.choices or (p.low, p.high)}"
                          for p in spec.params}}.items():
        client.log_param(run.info.run_id, key, str(value)[:6000])
    study.set_user_attr(PARENT_ATTR, run.info.run_id)
    return study


def _wait_until_enqueued_taken(study: optuna.Study, seconds: float = 60.0) -> None:
    """Start once the enqueued (default) trial is taken.  SQLite has no row locks: two processes can
    both take the one waiting trial, and the second then fails with "Cannot tell a COMPLETE trial"
    (seen on a slow machine).  One worker of a launch takes it; the others wait, at most ``seconds``
    (should that worker die first)."""
    deadline = time.monotonic() + seconds
    while study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.WAITING,)):
        if time.monotonic() > deadline:
            return
        time.sleep(0.5)


def _wait_for_parent(study: optuna.Study) -> str:
    deadline = time.monotonic() + PARENT_WAIT_SECONDS
    while PARENT_ATTR not in study.user_attrs:
        if time.monotonic() > deadline:
            raise RuntimeError(f"study {study.study_name}: no MLflow parent run recorded after "
                               f"{PARENT_WAIT_SECONDS} s (did the process that created the study fail?)")
        time.sleep(1.0)
    return study.user_attrs[PARENT_ATTR]


class _InterruptWithoutTraceback(logging.Filter):
    """Keeps a log line whose exception is a KeyboardInterrupt, without its traceback."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.exc_info and isinstance(record.exc_info[1], KeyboardInterrupt):
            record.exc_info, record.exc_text = None, None
        return True


def quiet_interrupts() -> None:
    """Optuna logs a trial stopped by Ctrl-C as failed, with the KeyboardInterrupt's traceback: its handlers
    keep the line (which trial, which parameters) and drop the traceback, as the sweep's own Ctrl-C line does."""
    for handler in logging.getLogger("optuna").handlers:
        if not any(isinstance(f, _InterruptWithoutTraceback) for f in handler.filters):
            handler.addFilter(_InterruptWithoutTraceback())


def run_trials(spec: SweepSpec, n_trials: int, worker: int, callbacks: Sequence[Any] = (),
               takes_enqueued: bool = True) -> int:
    """Run exactly ``n_trials`` trials of the study in this process; returns how many completed.
    ``callbacks`` are Optuna's (called with the study and each finished trial); ``takes_enqueued``:
    False for all but one of the processes of a launch (:func:`open_study`)."""
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    quiet_interrupts()
    os.environ.setdefault("DVC_ROOT", str(spec.root))  # the MLflow artefact root, as in the stages
    study = open_study(spec, worker, takes_enqueued)
    parent = study.user_attrs[PARENT_ATTR]
    client = mlflow_client(spec)
    experiment = tracking.experiment_id(client, SWEEP_EXPERIMENT)
    base = base_config(spec.root, spec.base_overrides)
    splits = load_splits(spec.root / layout(base).windows_file(spec.shape))
    completed = 0

    def objective(trial: optuna.Trial) -> float:
        nonlocal completed
        values = suggest(trial, list(spec.params))
        trial_overrides = overrides(list(spec.params), values)
        cfg = compose(spec.root, [*spec.base_overrides, *trial_overrides])
        tags = {"mlflow.parentRunId": parent, "sweep_study": spec.study, "optuna_trial": str(trial.number),
                "default_config": str(bool(trial.user_attrs.get("default_config"))).lower(),
                "worker": str(worker)}
        run = tracking.with_retry(lambda: client.create_run(experiment, run_name=f"trial-{trial.number}", tags=tags))
        run_id = run.info.run_id
        trial.set_user_attr("mlflow_run_id", run_id)
        for p, text in zip(spec.params, trial_overrides, strict=True):
            client.log_param(run_id, p.name, text.split("=", 1)[1])
        try:
            result = average([train_and_score(cfg, spec.shape, spec.model, spec.threads, splits, replicate)
                              for replicate in range(spec.replicates)])
            value = metric(result, spec.objective)
        except Exception:
            client.set_terminated(run_id, "FAILED")
            raise
        figures = {"objective": value, "val_f1": result["val"]["f1"], "val_accuracy": result["val"]["accuracy"],
                   "epochs_run": result["epochs_run"], "train_seconds": result["train_seconds"]}
        for key, number in figures.items():
            client.log_metric(run_id, key, float(number))
        for key in ("val_f1", "val_accuracy", "epochs_run"):
            trial.set_user_attr(key, figures[key])
        client.set_terminated(run_id)
        completed += 1
        return value

    study.optimize(objective, n_trials=n_trials, catch=(RuntimeError, ValueError, FloatingPointError),
                   callbacks=list(callbacks))
    return completed
