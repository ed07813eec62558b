"""The Optuna sweep (python -m toolpath.sweep) on smoke windows, in a temporary copy of conf/."""

import json
import os
import shutil
import subprocess
import sys
import time
import warnings

import mlflow
import optuna
import pytest
from omegaconf import OmegaConf

import toolpath.models  # noqa: F401  (before toolpath.models.training: the two import each other)
from conftest import REPO, copy_store
from toolpath.pipeline import config
from toolpath.pipeline.config import compose_config as compose
from toolpath.pipeline.settings import training as model_and_settings
from toolpath.stages import generate
from toolpath.sweep import overrides, parse_space
from toolpath.sweep.__main__ import _shares
from toolpath.sweep.__main__ import main as sweep_main

# one worker: the module's smoke windows are generated once, and the group starts early (conftest.LONG_GROUPS)
pytestmark = pytest.mark.xdist_group("sweep")
SMOKE = ["+experiment=smoke"]
# the smoke windows train in a second; a short epoch range keeps the trials short too
SWEEP = [*SMOKE, "sweep.study=mcrl-gear", "sweep.replicates=1", "sweep.space.epochs.low=1",
         "sweep.space.epochs.high=3", "sweep.space.epochs.step=1"]


@pytest.fixture(scope="module")
def windows_dir(tmp_path_factory, mlflow_template):
    """conf/ and smoke gear windows in a directory of their own (built once for the module)."""
    root = tmp_path_factory.mktemp("sweep")
    shutil.copytree(REPO / "conf", root / "conf")
    config.compose(SMOKE, root=root)
    old = os.getcwd()
    env = {k: os.environ.get(k) for k in ("MLFLOW_TRACKING_URI", "DVC_ROOT")}
    os.environ.update(MLFLOW_TRACKING_URI=copy_store(mlflow_template, root / "stages.db"), DVC_ROOT=str(root))
    try:
        os.chdir(root)
        generate.main(["--shape", "gear"])
    finally:
        os.chdir(old)
        for key, value in env.items():
            os.environ.pop(key) if value is None else os.environ.__setitem__(key, value)
    return root / "data" / "windows"


@pytest.fixture
def sweep_dir(tmp_path, windows_dir, monkeypatch, mlflow_template):
    shutil.copytree(REPO / "conf", tmp_path / "conf")
    shutil.copytree(windows_dir, tmp_path / "data" / "windows")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MLFLOW_TRACKING_URI", copy_store(mlflow_template, tmp_path / "mlflow.db"))
    monkeypatch.setenv("DVC_ROOT", str(tmp_path))
    monkeypatch.delenv("TOOLPATH_SWEEP_STORAGE", raising=False)
    return tmp_path


def test_a_launch_composes_its_base_configuration_once_per_content_of_conf(tmp_path):
    from omegaconf.errors import ReadonlyConfigError

    from toolpath.sweep.study import base_config

    shutil.copytree(REPO / "conf", tmp_path / "conf")
    first = base_config(tmp_path, SMOKE)
    assert base_config(tmp_path, SMOKE) is first  # read again, not composed again
    with pytest.raises(ReadonlyConfigError):  # so no reader can change what the next one reads
        first.seed = 1
    assert base_config(tmp_path, [*SMOKE, "seed=7"]).seed == 7  # other overrides: another composition
    config_file = tmp_path / "conf/config.yaml"
    config_file.write_text(config_file.read_text().replace(f"seed: {first.seed}", "seed: 11", 1))
    assert base_config(tmp_path, SMOKE).seed == 11  # conf/ changed (a tuned config adopted): composed again


def test_space_turns_samples_into_hydra_overrides():
    space = {"lr": {"key": "train.per_shape.{shape}.lr", "type": "float", "low": 1e-4, "high": 1e-2, "log": True},
             "hidden": {"key": "models.mcrl.mlp_hidden", "type": "choice", "choices": [[8, 4], [16, 8]]}}
    params = parse_space(space, "gear")
    assert [p.key for p in params] == ["train.per_shape.gear.lr", "models.mcrl.mlp_hidden"]
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=1))
    trial = study.ask()
    values = {p.name: p.value(p.suggest(trial)) for p in params}
    assert values["hidden"] in ([8, 4], [16, 8]) and 1e-4 <= values["lr"] <= 1e-2
    text = overrides(params, values)
    assert text[1] in ("models.mcrl.mlp_hidden=[8,4]", "models.mcrl.mlp_hidden=[16,8]")
    assert params[1].sampled([16, 8]) == "16,8" and params[1].sampled([1, 2]) is None
    assert params[0].sampled(1.0) is None  # outside [low, high]
    with pytest.raises(ValueError, match="sweep.space.bad: type"):
        parse_space({"bad": {"key": "x", "type": "normal"}}, "gear")
    with pytest.raises(ValueError, match="low < high"):
        parse_space({"bad": {"key": "x", "type": "float", "low": 1, "high": 1}}, "gear")
    assert _shares(5, 2) == [3, 2] and _shares(1, 4) == [1] and _shares(0, 2) == []


def _trial_runs(study, uri=None):
    client = mlflow.MlflowClient(tracking_uri=uri or os.environ["MLFLOW_TRACKING_URI"])
    runs = client.search_runs([client.get_experiment_by_name("cnc-curvature-sweeps").experiment_id])
    parent = [r for r in runs if r.data.tags.get("sweep_role") == "parent" and r.info.run_name == study]
    assert len(parent) == 1
    children = [r for r in runs if r.data.tags.get("mlflow.parentRunId") == parent[0].info.run_id]
    return parent[0], children


def test_smoke_sweep_runs_trials_in_parallel_logs_nested_runs_and_writes_the_tuned_config(sweep_dir):
    committed = (sweep_dir / "conf/model/mcrl_tuned.yaml").read_bytes()  # the defaults pick it
    assert sweep_main([*SWEEP, "sweep.n_trials=3", "sweep.workers=2"]) == 0
    assert (sweep_dir / "conf/model/mcrl_tuned.yaml").read_bytes() == committed  # conf/ is written only when asked
    assert sweep_main(["--adopt", *SWEEP, "sweep.n_trials=3"]) == 0  # the study is complete: nothing more runs
    study = optuna.load_study(study_name="mcrl-gear", storage=f"sqlite:///{sweep_dir}/optuna.db")
    assert [t.state.name for t in study.trials] == ["COMPLETE"] * 3
    assert study.trials[0].user_attrs["default_config"]  # trial 0 is the composed configuration
    parent, children = _trial_runs("mcrl-gear")
    assert sorted(r.info.run_name for r in children) == ["trial-0", "trial-1", "trial-2"]
    assert {r.data.tags["worker"] for r in children} == {"0", "1"}  # two processes ran trials
    best = [r for r in children if r.data.tags.get("best_trial") == "true"]
    assert len(best) == 1 and best[0].info.run_name == f"trial-{study.best_trial.number}"
    assert parent.data.metrics["best_value"] == pytest.approx(study.best_value)
    assert best[0].data.metrics["objective"] == pytest.approx(study.best_value)
    summary = json.loads((sweep_dir / "reports/sweep/mcrl-gear.json").read_text())
    assert summary["best"]["number"] == study.best_trial.number and summary["default"]["number"] == 0
    assert (sweep_dir / "reports/figures/sweep_mcrl-gear_history.png").stat().st_size > 1000
    importance = sweep_dir / "reports/figures/sweep_mcrl-gear_importance.png"  # fANOVA needs a spread of scores
    assert importance.stat().st_size > 1000 if importance.exists() else \
        summary["figures"]["importance"].startswith("not drawn: ")
    # the tuned config is a model config the train stage accepts, schedule included
    tuned = OmegaConf.load(sweep_dir / "conf/model/mcrl_tuned.yaml")
    assert tuned._target_ == "toolpath.models.MCRL" and tuned.dropout == pytest.approx(study.best_params["dropout"])
    # outside Table 3's protocol (whose settings win over a model's own schedule, tests/test_config.py)
    cfg = compose(sweep_dir, [*SMOKE, "model@models.mcrl=mcrl_tuned", "train.protocol.models=[]"])
    network, settings = model_and_settings(cfg, "gear", "mcrl")
    assert "schedule" not in network and settings["lr"] == pytest.approx(study.best_params["lr"])
    assert settings["epochs"] == study.best_params["epochs"]
    assert settings["clip_grad_norm"] == study.best_params["clip_grad_norm"]  # a train.common key, this model only
    assert model_and_settings(cfg, "gear", "mlp")[1]["clip_grad_norm"] == cfg.train.common.clip_grad_norm
    # train.common.lr replaces each shape's rate; a tuned schedule is more specific still
    plain = compose(sweep_dir, [*SMOKE, "train.common.lr=0.0042", "train.protocol.models=[]"])
    assert model_and_settings(plain, "gear", "mlp")[1]["lr"] == 0.0042
    tuned_too = compose(sweep_dir, [*SMOKE, "train.common.lr=0.0042", "model@models.mcrl=mcrl_tuned",
                                    "train.protocol.models=[]"])
    assert model_and_settings(tuned_too, "gear", "mcrl")[1]["lr"] == pytest.approx(study.best_params["lr"])
    # a resumed study continues: one more trial, numbered 3
    assert sweep_main([*SWEEP, "sweep.n_trials=4", "sweep.workers=2"]) == 0
    study = optuna.load_study(study_name="mcrl-gear", storage=f"sqlite:///{sweep_dir}/optuna.db")
    assert [t.number for t in study.trials] == [0, 1, 2, 3]
    assert len(_trial_runs("mcrl-gear")[1]) == 4
    # nothing left to run: the same command only refreshes the outputs
    assert sweep_main([*SWEEP, "sweep.n_trials=4"]) == 0
    assert len(optuna.load_study(study_name="mcrl-gear", storage=f"sqlite:///{sweep_dir}/optuna.db").trials) == 4


def test_one_worker_sweeps_repeat_exactly_for_a_seed(sweep_dir):
    results = []
    for name in ("a", "b"):
        assert sweep_main([*SWEEP, "sweep.n_trials=2", "sweep.workers=1", f"sweep.study={name}"]) == 0
        study = optuna.load_study(study_name=name, storage=f"sqlite:///{sweep_dir}/optuna.db")
        results.append([(t.params, t.value) for t in study.trials])
    assert results[0] == results[1]


def test_separate_launches_on_one_study_sample_with_their_own_seeds(sweep_dir):
    """Two launches one after the other on one study (as two terminals would): the second claims the
    next worker indices, so its sampler seed differs and it does not repeat the first's trials."""
    from toolpath.sweep.study import claim_workers, open_study, spec_from

    base = ["+sweep=mcrl", *SWEEP, "sweep.workers=1", "model@models.mcrl=mcrl"]
    spec = spec_from(compose(sweep_dir, base), sweep_dir, base)
    study = open_study(spec)
    assert [claim_workers(spec, study, 2), claim_workers(spec, study, 1), claim_workers(spec, study, 3)] == [0, 2, 3]
    assert study.user_attrs["workers_claimed"] == 6
    for _ in range(2):  # two launches, one trial each past the default one
        assert sweep_main(["--trials", "2", *SWEEP, "sweep.workers=1"]) == 0
    trials = optuna.load_study(study_name="mcrl-gear", storage=f"sqlite:///{sweep_dir}/optuna.db").trials
    sampled = [tuple(sorted(t.params.items())) for t in trials if not t.user_attrs.get("default_config")]
    assert len(sampled) == 3 and len(set(sampled)) == 3


def test_one_worker_of_a_launch_takes_the_default_trial_and_only_the_others_wait(sweep_dir, monkeypatch):
    """The process that takes the enqueued default trial starts at once (each launch once lost 60 s
    waiting for a creator that never takes trials); the others start as soon as it is taken."""
    from toolpath.sweep import study as study_module

    base = ["+sweep=mcrl", *SWEEP, "sweep.workers=2", "model@models.mcrl=mcrl"]
    spec = study_module.spec_from(compose(sweep_dir, base), sweep_dir, base)
    created = study_module.open_study(spec)
    waiting = (optuna.trial.TrialState.WAITING,)
    assert len(created.get_trials(states=waiting)) == 1

    def no_sleep(seconds):
        raise AssertionError("the worker taking the default trial waited")

    monkeypatch.setattr(study_module.time, "sleep", no_sleep)
    study_module.open_study(spec, 0, takes_enqueued=True)
    naps = []

    def taken_meanwhile(seconds):  # the first worker takes it while this one waits
        naps.append(seconds)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # Optuna: a heartbeat storage is meant for optimize(), not ask()
            created.ask()

    monkeypatch.setattr(study_module.time, "sleep", taken_meanwhile)
    joined = study_module.open_study(spec, 1, takes_enqueued=False)
    assert len(naps) == 1 and not joined.get_trials(states=waiting)


def test_bad_input_gives_a_message_and_exit_2(sweep_dir, capsys):
    assert sweep_main(["--config", "nope"]) == 2
    assert "conf/sweep/nope.yaml not found" in capsys.readouterr().err
    assert sweep_main([*SMOKE, "sweep.shape=maple_leaf"]) == 2  # no windows for that shape here
    assert "dvc repro generate@maple_leaf" in capsys.readouterr().err
    assert sweep_main([*SMOKE, "sweep.model=unknown"]) == 2
    assert "sweep.model" in capsys.readouterr().err
    (sweep_dir / "optuna.db").write_bytes(bytes(range(256)) * 40)  # a damaged study database
    assert sweep_main([*SWEEP, "sweep.n_trials=1"]) == 2
    err = capsys.readouterr().err
    assert "optuna.db: not a usable Optuna study storage" in err and "Traceback" not in err


def test_ctrl_c_ends_with_one_line_and_exit_130(sweep_dir, capsys, monkeypatch):
    """Ctrl-C during the trials: one line, no traceback (the study keeps what finished; a resumed study
    runs the trials still missing, as test_smoke_sweep_... shows)."""
    from toolpath.sweep import study as study_module

    real = study_module.run_trials

    def interrupted(spec, n_trials, *args, **kwargs):  # the worker sets up, then Ctrl-C before its first trial
        real(spec, 0, *args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(study_module, "run_trials", interrupted)
    assert sweep_main([*SWEEP, "sweep.n_trials=2", "sweep.workers=1"]) == 130
    err = capsys.readouterr().err
    assert "sweep stopped: every finished trial is kept" in err and "Traceback" not in err
    # a trial the Ctrl-C stops is logged by Optuna as failed: the worker set its handlers to keep the line
    # and drop the traceback
    import logging

    handlers = logging.getLogger("optuna").handlers
    assert handlers
    for handler in handlers:
        for error, shown in ((KeyboardInterrupt(), False), (ValueError("a real failure"), True)):
            try:
                raise error
            except BaseException:
                record = logging.getLogger("optuna.study._optimize").makeRecord(
                    "optuna.study._optimize", logging.WARNING, __file__, 1, "Trial 4 failed", (), sys.exc_info())
            assert handler.filter(record)
            assert ("Traceback" in handler.format(record)) == shown and "Trial 4 failed" in handler.format(record)


POSTGRES = os.environ.get("TOOLPATH_TEST_POSTGRES")


@pytest.mark.postgres
@pytest.mark.skipif(not POSTGRES, reason="TOOLPATH_TEST_POSTGRES not set (.ci/run starts a PostgreSQL server)")
def test_two_workers_share_one_study_in_postgresql(sweep_dir):
    """Two sweep processes (as on two machines) against one PostgreSQL database, concurrently."""
    import sqlalchemy

    tag = f"t{os.getpid()}_{int(time.time())}"
    admin = sqlalchemy.create_engine(f"{POSTGRES}/postgres", isolation_level="AUTOCOMMIT")
    with admin.connect() as conn:
        for db in ("optuna", "mlflow"):
            conn.execute(sqlalchemy.text(f"CREATE DATABASE {db}_{tag}"))
    admin.dispose()
    env = {**os.environ, "TOOLPATH_SWEEP_STORAGE": f"{POSTGRES}/optuna_{tag}",
           "MLFLOW_TRACKING_URI": f"{POSTGRES}/mlflow_{tag}"}
    cmd = [sys.executable, "-m", "toolpath.sweep", "--trials", "2", *SWEEP, "sweep.workers=1"]
    workers = [subprocess.Popen(cmd, cwd=sweep_dir, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True) for _ in range(2)]
    outputs = [w.communicate(timeout=600)[0] for w in workers]
    assert [w.returncode for w in workers] == [0, 0], "\n".join(o[-2000:] for o in outputs)
    storage = optuna.storages.RDBStorage(env["TOOLPATH_SWEEP_STORAGE"])
    trials = optuna.load_study(study_name="mcrl-gear", storage=storage).trials
    storage.engine.dispose()
    assert sorted(t.number for t in trials) == list(range(4))  # none lost, none twice
    assert all(t.state.name == "COMPLETE" for t in trials)
    sampled = [tuple(sorted(t.params.items())) for t in trials if not t.user_attrs.get("default_config")]
    assert len(set(sampled)) == len(sampled) == 3  # each launch sampled with its own seed
    assert sum(bool(t.user_attrs.get("default_config")) for t in trials) == 1
    _, children = _trial_runs("mcrl-gear", env["MLFLOW_TRACKING_URI"])
    assert sorted(int(r.data.tags["optuna_trial"]) for r in children) == list(range(4))
    assert sum(r.data.tags.get("best_trial") == "true" for r in children) == 1


def test_a_trial_scores_the_mean_of_its_replicates_by_hand():
    from toolpath.sweep.objective import average

    one = {"val": {"f1": 0.8, "accuracy": 0.9, "per_class": {}}, "test": {"f1": 0.7, "accuracy": 0.8},
           "epochs_run": 4, "train_seconds": 2.0}
    two = {"val": {"f1": 0.9, "accuracy": 0.95, "per_class": {}}, "test": {"f1": 0.75, "accuracy": 0.9},
           "epochs_run": 6, "train_seconds": 3.0}
    merged = average([one, two])
    assert merged["val"] == {"f1": pytest.approx(0.85), "accuracy": pytest.approx(0.925)}
    assert merged["test"]["accuracy"] == pytest.approx(0.85) and merged["epochs_run"] == 5.0
    assert merged["train_seconds"] == 5.0


def test_the_swept_model_leaves_the_protocol_whose_settings_would_win_over_the_sampled_keys():
    from toolpath.sweep.study import outside_protocol

    cfg = OmegaConf.create({"train": {"protocol": {"models": ["mcrl_xy", "mcrl", "mlp"]}}})
    assert outside_protocol(cfg, "mcrl") == ["train.protocol.models=[mcrl_xy,mlp]"]
    assert outside_protocol(cfg, "cnn") == []  # not listed: nothing to take out
    assert outside_protocol(OmegaConf.create({"train": {}}), "mcrl") == []
