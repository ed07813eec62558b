"""Bad configuration values are refused in one line before any stage runs (toolpath.pipeline.schema)."""

import shutil

import pytest
from omegaconf import OmegaConf

from conftest import REPO
from toolpath.pipeline import config
from toolpath.pipeline.schema import ConfigError


@pytest.fixture
def checkout(tmp_path, monkeypatch):
    """conf/ and params.yaml of the repository in a scratch folder (with DVC's tmp folder for the stamp)."""
    shutil.copytree(REPO / "conf", tmp_path / "conf")
    shutil.copy(REPO / "params.yaml", tmp_path / "params.yaml")
    (tmp_path / ".dvc" / "tmp").mkdir(parents=True)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("override, message", [
    ("train.per_shape.gear.epochs=-1", "train.per_shape.gear.epochs = -1: must be a whole number >= 1"),
    ("train.per_model={rnn: {epochs: 0}}", "train.per_model.rnn.epochs = 0: must be a whole number >= 1"),
    ("label.window=0", "label.window = 0: must be a whole number >= 10"),
    ("label.window=4", "label.window = 4: must be a whole number >= 10"),
    ("optimize.tolerance=-0.1", "optimize.tolerance = -0.1: must be a number > 0"),
    ("optimize.tolerance=nan", "optimize.tolerance = nan: must be a number > 0"),
    ("feedrate.band=-0.5", "feedrate.band = -0.5: must be a number >= 0 (or null)"),
    ("seed=abc", "seed = 'abc': must be a whole number >= 0"),
    ("gcode.read.chord_tolerance=0", "gcode.read.chord_tolerance = 0: must be a number > 0"),
    ("resources.workers.train=0", "resources.workers.train = 0: must be a whole number >= 1"),
    ("train.common.restore_best=maybe", "train.common.restore_best = 'maybe': must be true or false"),
    ("qat.freeze_last=3", "qat.freeze_last = 3: must be below qat.epochs (3)"),
    ("label.split.test=0.6", "the fractions must sum to 1"),
    ("label.bounds=[3.5,1.9,7.6]", "label.bounds = [3.5, 1.9, 7.6]: must be three increasing positive numbers"),
    ("shapes=[gear,star]", "shapes: 'star' has no generate.star section; the configured shapes are gear, pentagram"),
    ("+label.windw=50", "label.windw: unknown key; label has window, stride, bounds, split"),
    ("+foo=1", "foo: unknown key; the top level has"),
    ("foo=1", "Could not override 'foo'"),
    ("+experiment=smok", "Could not find 'experiment/smok'"),
    ("train.per_shape.gear.epochs=", "train.per_shape.gear.epochs = '': must be a whole number >= 1"),
    ("shapes=gear", "shapes = 'gear': must be a list"),
    ("models.mcrl.schedule.per_shape.gear.epochs=0", "models.mcrl.schedule.per_shape.gear.epochs = 0: must be a whole"),
    ("+models.mcrl.schedule.per_shape.star.epochs=3", "models.mcrl.schedule.per_shape.star: no such shape"),
    ("train.common.lr=0.001", "train.common.lr = 0.001: no trained model uses it, since train.protocol.models lists"),
])
def test_bad_values_are_one_line_and_params_yaml_stays(checkout, capsys, override, message):
    before = (checkout / "params.yaml").read_bytes()
    assert config.main([override]) == 1
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert (checkout / "params.yaml").read_bytes() == before


def test_a_common_rate_is_refused_only_when_no_trained_model_would_use_it(checkout):
    assert config.main(["train.common.lr=0.001", "train.protocol.models=[]"]) == 0  # Table 2's schedules: used
    assert config.main(["train.common.lr=0.001", "train.protocol.models=[mlp]"]) == 0  # the others use it
    assert config.main(["train.common.lr=0.001", "train.models=[rule]"]) == 1  # the rule has no rate


def test_a_section_replaced_by_a_value_is_one_line_not_a_traceback():
    from toolpath.pipeline.schema import problems

    reference = {"label": {"window": 50, "bounds": [1.9, 3.5, 7.6]}, "qat": {"epochs": 3}, "shapes": ["gear"]}
    found = list(problems({"label": 5, "qat": "x", "shapes": ["gear"]}, reference))
    assert found[:2] == ["label = 5: must be a section with window, bounds", "qat = 'x': must be a section with epochs"]


def test_unknown_experiment_lists_the_valid_ones(checkout, capsys):
    assert config.main(["+experiment=smok"]) == 1
    err = capsys.readouterr().err
    assert "paper" in err and "smoke" in err


@pytest.mark.parametrize("profile", [[], ["+experiment=smoke"], ["+experiment=paper"]])
def test_every_profile_passes(checkout, profile):
    assert config.main(profile) == 0


def test_a_stage_refuses_a_bad_params_yaml_before_any_work(checkout):
    params = OmegaConf.load(checkout / "params.yaml")
    params.train.per_shape.gear.epochs = -1
    OmegaConf.save(params, checkout / "params.yaml")
    with pytest.raises(ConfigError, match=r"params.yaml: train.per_shape.gear.epochs = -1: must be a whole number"):
        config.load(checkout / "params.yaml")
    (checkout / "params.yaml").write_text("train: [unclosed\n")
    with pytest.raises(ConfigError, match="params.yaml: not a readable configuration"):
        config.load(checkout / "params.yaml")


def test_a_checked_params_yaml_is_not_checked_again(checkout, monkeypatch):
    config.load(checkout / "params.yaml")
    assert (checkout / ".dvc/tmp/params-checked").is_file()
    monkeypatch.setattr(config, "validate", lambda *a, **k: pytest.fail("checked twice"))
    config.load(checkout / "params.yaml")


def test_the_kept_reference_follows_conf_and_cannot_be_changed_by_a_caller(checkout):
    first = config.reference(checkout)
    first["label"]["window"] = -1  # a caller's change stays in its copy
    assert config.reference(checkout)["label"]["window"] == OmegaConf.load(checkout / "conf/label/default.yaml").window
    label = checkout / "conf/label/default.yaml"
    label.write_text(label.read_text().replace("window: ", "window: 1", 1))  # conf/ changed: composed again
    assert OmegaConf.load(label).window >= 100 and config.reference(checkout)["label"]["window"] == \
        OmegaConf.load(label).window
