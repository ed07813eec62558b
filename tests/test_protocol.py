"""Table 3's one protocol: the same settings for every model it lists, learning rates chosen on
validation programs only (``python -m toolpath.sweep.protocol``), the committed study consistent."""

import json

import numpy as np
import pytest
from omegaconf import OmegaConf

from conftest import REPO, easy_split, write_windows
from toolpath.pipeline.settings import training
from toolpath.sweep import protocol

CFG = OmegaConf.load(REPO / "params.yaml")
STUDY = REPO / "reports/tuning/protocol.json"


def test_every_model_of_the_protocol_trains_the_same_settings_but_its_rate():
    listed = list(CFG.train.protocol.models)
    assert len(listed) >= 2
    for shape in CFG.shapes:
        runs = {m: training(CFG, shape, m)[1] for m in listed}
        own = {"lr", "seed", *(k for option in CFG.train.protocol.get("structure", {}).values() for k in option)}
        shared = [{k: v for k, v in s.items() if k not in own} for s in runs.values()]
        assert all(s == shared[0] for s in shared)
        assert all(runs[m]["lr"] == CFG.train.protocol.lr[m] for m in listed)
        assert shared[0]["epochs"] == CFG.train.protocol.settings.epochs and shared[0]["augment"] is True
        learned = [m for m in CFG.train.models if CFG.models[m]["_target_"] != "toolpath.models.LocalCurvatureRule"]
        assert set(listed) == set(learned)  # every learned model of both Table 3 blocks
        assert {CFG.models[m].get("inputs", "turning") for m in listed} == {"turning", "coordinates"}
        for model, option in CFG.train.protocol.get("structure", {}).items():  # a structural choice, applied
            assert all(runs[model][k] == v for k, v in option.items())


def test_the_configured_rates_are_the_committed_study_s_choice():
    if not STUDY.exists():
        pytest.fail(f"{STUDY.relative_to(REPO)} is missing: run `python -m toolpath.sweep.protocol`")
    study = json.loads(STUDY.read_text())
    assert study["split"] == "val" and study["shape"] == CFG.train.protocol.tune.shape
    assert study["grid"] == list(CFG.train.protocol.tune.lr)
    assert study["chosen"] == {m: CFG.train.protocol.lr[m] for m in CFG.train.protocol.models}
    assert study["chosen_structure"] == OmegaConf.to_container(CFG.train.protocol.structure)
    assert protocol.choose(study["trials"]) == (study["chosen"], study["chosen_structure"])  # self-consistent
    settings = OmegaConf.to_container(CFG.train.protocol.settings)
    assert study["settings"] == settings


def test_choose_takes_the_highest_validation_f1_and_the_earlier_trial_on_a_tie():
    trials = [{"model": "a", "lr": 0.001, "val_f1": 0.9}, {"model": "a", "lr": 0.002, "val_f1": 0.8},
              {"model": "a", "lr": 0.004, "val_f1": 0.9}, {"model": "b", "lr": 0.001, "val_f1": 0.6},
              {"model": "b", "lr": 0.002, "val_f1": 0.7, "structure": {"aux_loss_weight": 0.0}},
              {"model": "b", "lr": 0.001, "val_f1": 0.75, "structure": {"aux_loss_weight": 0.5}}]
    assert protocol.choose(trials) == ({"a": 0.001, "b": 0.001}, {"b": {"aux_loss_weight": 0.5}})


def test_the_tuning_never_loads_the_test_split(tmp_path, monkeypatch):
    from toolpath.pipeline import artifacts

    X, y = easy_split(96)
    split = np.arange(96) % 3  # train, val and test windows all present in the file
    (tmp_path / "conf").symlink_to(REPO / "conf")
    write_windows(tmp_path / "data/windows/gear.npz", X, y + 1, split, program=np.arange(96) % 12)
    original = artifacts.WindowSet.part

    def guarded(self, which):
        assert which != artifacts.Split.TEST, "the tuning read the test split"
        return original(self, which)

    monkeypatch.setattr(artifacts.WindowSet, "part", guarded)
    monkeypatch.chdir(tmp_path)
    protocol.main(["+experiment=smoke", "train.protocol.models=[mlp_xy,mcrl_xy]", "resources.workers.train=1"])
    study = json.loads((tmp_path / "reports/tuning/protocol.json").read_text())
    tried = [(t["model"], t["structure"].get("aux_loss_weight"), t["lr"]) for t in study["trials"]]
    assert tried == [("mlp_xy", None, 1e-3), ("mlp_xy", None, 3e-3), ("mcrl_xy", 0.0, 1e-3), ("mcrl_xy", 0.0, 3e-3),
                     ("mcrl_xy", 0.5, 1e-3), ("mcrl_xy", 0.5, 3e-3)]  # the listed order: options, then rates
    assert set(study["chosen"]) == {"mlp_xy", "mcrl_xy"} and set(study["chosen_structure"]) == {"mcrl_xy"}
    assert (tmp_path / "reports/tuning/protocol.png").stat().st_size > 0
    assert "**" in (tmp_path / "reports/tuning/protocol.md").read_text()


class Recording(dict):
    """A parts mapping that logs which split is read, and when."""

    def __init__(self, parts, log):
        super().__init__(parts)
        self.log = log

    def __getitem__(self, key):
        self.log.append(f"read {key}")
        return super().__getitem__(key)


def test_training_reads_the_test_split_only_after_the_model_is_fitted(monkeypatch):
    """The train stage's and every sweep's one training call: fitting sees train and val only."""
    from toolpath.models.training import classifier

    X, y = easy_split(48)
    log: list[str] = []
    fit = classifier.TorchClassifier.fit

    def logged_fit(self, *args, **kwargs):
        log.append("fit starts")
        out = fit(self, *args, **kwargs)
        log.append("fit ends")
        return out

    monkeypatch.setattr(classifier.TorchClassifier, "fit", logged_fit)
    parts = Recording({"train": (X[:24], y[:24] + 1), "val": (X[24:36], y[24:36] + 1),
                       "test": (X[36:], y[36:] + 1)}, log)
    network = {"_target_": "toolpath.models.MLP", "hidden": [8], "inputs": "turning"}
    classifier.fit_and_score(network, {"epochs": 1, "batch_size": 8}, None, parts)
    assert "read test" in log and log.index("read test") > log.index("fit ends")


def test_the_optuna_sweep_loads_no_test_windows(tmp_path):
    from toolpath.sweep.objective import load_splits

    X, y = easy_split(30)
    path = write_windows(tmp_path / "gear.npz", X, y + 1, np.arange(30) % 3)
    assert set(load_splits(path)) == {"train", "val"}
