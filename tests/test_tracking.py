"""The MLflow store shared by parallel writers (DVC queue workers, sweep workers)."""

import multiprocessing
import os

import pytest

from toolpath.pipeline import tracking


def _open_store(uri: str) -> str:
    os.environ["MLFLOW_TRACKING_URI"] = uri
    store = tracking.client()
    return tracking.experiment_id(store)


def test_processes_opening_a_new_sqlite_store_at_once_all_succeed(tmp_path):
    """A new store is migrated by whoever opens it first; without the init lock, two processes
    migrating one file at once fail ('duplicate column name', alembic row mismatch)."""
    uri = f"sqlite:///{tmp_path}/mlflow.db?timeout=60"
    with multiprocessing.get_context("spawn").Pool(3) as pool:
        ids = pool.map(_open_store, [uri] * 3)
    assert len(set(ids)) == 1  # one experiment, created once


def test_default_store_is_the_sqlite_file_at_the_repository_root(monkeypatch, tmp_path):
    """Without MLFLOW_TRACKING_URI the store is DVC_ROOT/mlflow.db (also for a queued experiment, which runs
    in a temporary copy): opening it creates that file and the project's experiment, and a second client
    finds the same experiment."""
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    monkeypatch.setenv("DVC_ROOT", str(tmp_path))
    first = tracking.experiment_id(tracking.client())
    assert (tmp_path / "mlflow.db").is_file()
    assert tracking.experiment_id(tracking.client()) == first


def test_retry_gives_up_on_errors_that_are_not_races():
    calls = []

    def flaky():
        calls.append(1)
        if len(calls) < 3:
            raise RuntimeError("database is locked")
        return "ok"

    assert tracking.with_retry(flaky) == "ok" and len(calls) == 3
    calls.clear()

    def wrong():
        calls.append(1)
        raise ValueError("bad value")

    with pytest.raises(ValueError):
        tracking.with_retry(wrong)
    assert len(calls) == 1  # not a race: not retried


def test_each_dvc_invocation_has_its_own_parent_and_names_the_run_behind_a_skipped_stage(mlflow_store, monkeypatch):
    monkeypatch.setenv("DVC_EXP_NAME", "exp-a")
    monkeypatch.setattr(tracking, "dvc_invocation", lambda: ("111-1", 1_000))
    with tracking.stage_run("label@gear"):
        pass
    with tracking.stage_run("train@gear"):
        pass
    first = tracking.parent_run_id()
    monkeypatch.setattr(tracking, "dvc_invocation", lambda: ("222-2", 2_000))  # a later `dvc repro`: train only
    with tracking.stage_run("train@gear"):
        pass
    second = tracking.parent_run_id()
    assert second != first
    skipped = tracking.record_up_to_date({"label", "train"})
    assert list(skipped) == ["up_to_date.label.gear"] and "exp-a" in skipped["up_to_date.label.gear"]
    store = tracking.client()
    label_run = store.get_run(first)  # the first parent started with its dvc process and ended after its stages
    assert label_run.info.start_time == 1_000 and label_run.info.end_time > 1_000
    assert store.get_run(second).data.tags["up_to_date.label.gear"] == skipped["up_to_date.label.gear"]


def test_one_dvc_process_keeps_one_parent_when_its_start_time_drifts(mlflow_store, monkeypatch):
    """psutil's start of one `dvc repro` moved 8 s in 35 minutes here: three parents for one pipeline."""
    monkeypatch.setenv("DVC_EXP_NAME", "exp-drift")
    monkeypatch.setattr(tracking, "dvc_invocation", lambda: ("5761-1796392462", 1_796_392_462_990))
    first = tracking.parent_run_id()
    monkeypatch.setattr(tracking, "dvc_invocation", lambda: ("5761-1796392470", 1_796_392_470_990))
    assert tracking.parent_run_id() == first
    monkeypatch.setattr(tracking, "dvc_invocation", lambda: ("5762-1796392470", 1_796_392_470_990))  # another dvc
    assert tracking.parent_run_id() != first
    monkeypatch.setattr(tracking, "dvc_invocation", lambda: ("5761-1796399000", 1_796_399_000_000))  # pid reused later
    assert tracking.parent_run_id() != first


@pytest.mark.parametrize(("profile", "command"), [("default", "&& make repro`"),
                                                  ("paper", "config +experiment=paper && .venv/bin/dvc repro`")])
def test_the_parent_description_reproduces_its_profile(monkeypatch, tmp_path, profile, command):
    """`make repro` composes the default profile, so another profile is reproduced with `dvc repro`."""
    (tmp_path / "params.yaml").write_text(f"profile: {profile}\n")
    monkeypatch.setenv("DVC_ROOT", str(tmp_path))
    text = tracking._description("111-1")
    assert f"profile `{profile}`" in text and command in text
    assert ("+experiment=" in text) == (profile != "default")


def test_a_stage_run_records_system_metrics(mlflow_store, monkeypatch):
    """CPU and memory are sampled while a stage works (MLflow's system metrics), so the run's chart shows them."""
    import time

    monkeypatch.setattr(tracking, "SYSTEM_METRICS_SECONDS", 0.2)
    monkeypatch.setattr(tracking, "dvc_invocation", lambda: ("333-3", 1_000))
    with tracking.stage_run("label@gear") as run:
        time.sleep(1.5)
    metrics = tracking.client().get_run(run.info.run_id).data.metrics
    assert any(name.startswith("system/cpu_utilization") for name in metrics), sorted(metrics)
    assert any(name.startswith("system/system_memory_usage") for name in metrics), sorted(metrics)
