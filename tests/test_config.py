"""conf/ is the one source of truth: params.yaml is its composition, dvc.yaml reads existing keys."""

import csv
import json
import re
import sys

import pytest
import yaml
from omegaconf import OmegaConf

from conftest import REPO
from toolpath.pipeline import config


def test_params_yaml_is_the_composition_of_conf(tmp_path):
    out = config.compose([], root=REPO, output=tmp_path / "params.yaml")
    committed = (REPO / "params.yaml").read_bytes()
    assert out.read_bytes() == committed, "params.yaml drifted from conf/: run `python -m toolpath.pipeline.config`"


def test_a_composition_kept_for_its_groups_takes_value_overrides_as_hydra_does(tmp_path, monkeypatch):
    """compose_config keeps the merged groups and sets the values itself: what it gives is what DVC's own
    composition writes, and a bad value fails as Hydra fails; a Hydra without the function composes whole."""
    for overrides in (["+experiment=smoke", "shapes=[gear]", "train.protocol.lr.mlp=1e-3"],  # on a chosen group
                      ["model@models.mcrl=mcrl", "models.mcrl.dropout=0.1", "+extra.key=3", "~models.rule", "++seed=5"],
                      ["train={models: [mlp]}", "seed=${train.common.lr}"]):  # a dict for a group's name: a value
        written = config.compose(overrides, root=REPO, output=tmp_path / "p.yaml").read_text()
        for _ in range(2):  # the second time from the kept composition
            assert OmegaConf.to_yaml(config.compose_config(REPO, overrides)) == written
    with monkeypatch.context() as patch:  # Hydra's own code keeps the module it imported; ours cannot import it
        patch.setitem(sys.modules, "hydra._internal.config_loader_impl", None)
        patch.setattr(config, "_MERGED", {})
        assert OmegaConf.to_yaml(config.compose_config(REPO, overrides)) == written and not config._MERGED

    def outcome(compose, bad):
        try:
            return OmegaConf.to_yaml(compose(["+experiment=smoke", *bad]))
        except Exception as exc:  # noqa: BLE001 - Hydra's and OmegaConf's kinds alike: compared, not raised
            return type(exc).__name__, str(exc)

    def hydra(given):
        cfg = config._hydra_compose(REPO / "conf", given)
        OmegaConf.resolve(cfg)
        return cfg

    for bad in (["nonexist=3"], ["+seed=4"], ["~models.nope"], ["seed=1,2"]):
        expected = outcome(hydra, bad)
        assert isinstance(expected, tuple)
        assert outcome(lambda given: config.compose_config(REPO, given), bad) == expected


@pytest.mark.parametrize("experiment", sorted(p.stem for p in (REPO / "conf" / "experiment").glob("*.yaml")))
def test_every_experiment_composes(tmp_path, experiment):
    cfg = OmegaConf.load(config.compose([f"+experiment={experiment}"], root=REPO, output=tmp_path / "p.yaml"))
    assert cfg.profile == experiment
    for shape in cfg.shapes:
        assert cfg.generate[shape].programs >= 1


def _targets(node, path: str = ""):
    """Every (path, node) of a config with a ``_target_``."""
    if isinstance(node, dict):
        if "_target_" in node:
            yield path, node
        for key, value in node.items():
            yield from _targets(value, f"{path}.{key}" if path else str(key))


@pytest.mark.parametrize("experiment", [None, *sorted(p.stem for p in (REPO / "conf" / "experiment").glob("*.yaml"))])
def test_every_target_in_every_profile_instantiates_so_no_key_is_unused(tmp_path, experiment):
    """A node with ``_target_`` is built with every key as an argument: a dead or misspelt key fails.
    A model's ``schedule`` (a tuned model) is training settings: its keys must be training settings."""
    from hydra.utils import instantiate

    from toolpath.models.registry import schedule_for_shape, split_schedule
    from toolpath.models.training.loop import TrainSettings

    overrides = [f"+experiment={experiment}"] if experiment else []
    cfg = OmegaConf.load(config.compose(overrides, root=REPO, output=tmp_path / "p.yaml"))
    found = dict(_targets(OmegaConf.to_container(cfg, resolve=True)))
    expected = {"gcode.read", "gcode.write", "feedrate.machine", "corner.pso", "optimize.nacoa", "models.mcrl"}
    assert expected <= set(found)
    for path, node in found.items():
        if path.startswith("models."):
            node, schedule = split_schedule(node)
            for shape in cfg.shapes:
                TrainSettings(**schedule_for_shape(schedule, shape))  # an unknown key fails here
        try:
            instantiate(node, _convert_="all")
        except Exception as exc:  # noqa: BLE001 - the message names the node
            pytest.fail(f"{experiment or 'default'}: {path} does not build: {exc}")


def test_the_paper_profile_runs_table2_as_printed(tmp_path):
    from toolpath.reports.paper import TABLE2

    paper = OmegaConf.load(config.compose(["+experiment=paper"], root=REPO, output=tmp_path / "p.yaml"))
    for shape, (lr, rate, steps, batch, epochs, _) in TABLE2.items():
        train = paper.train.per_shape[shape]
        assert (train.lr, train.decay_rate, train.decay_steps, train.batch_size, train.epochs) == \
            (lr, rate, steps, batch, epochs), shape


def test_label_bounds_drive_labelling_the_rule_and_the_report():
    """One source for Table 1's thresholds: conf/label, read by the labeller, the rule and the report."""
    params = OmegaConf.load(REPO / "params.yaml")
    assert list(params.models.rule.bounds) == list(params.label.bounds)
    assert "label.bounds" in (REPO / "dvc.yaml").read_text()
    from toolpath.gcode import read_text
    from toolpath.geometry.labels import label_program

    zigzag = read_text("G1 X0 Y0\n" + "".join(f"G1 X{i} Y{i % 2}\n" for i in range(1, 60)))
    assert label_program(zigzag).label.tolist() == [4]
    assert label_program(zigzag, bounds=(100.0, 200.0, 300.0)).label.tolist() == [1]


def _matrix_items(stage: dict, params) -> list[dict]:
    """Every combination of a stage's matrix, its lists resolved from params.yaml."""
    items = [{}]
    for key, ref in stage.get("matrix", {}).items():
        values = OmegaConf.select(params, ref[2:-1]) if isinstance(ref, str) else ref
        items = [{**item, key: v} for item in items for v in values]
    return items


def test_every_dvc_params_key_exists():
    params = OmegaConf.load(REPO / "params.yaml")
    stages = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]
    assert set(stages) >= {"generate", "train", "sequence"}
    for name, stage in stages.items():
        for item in _matrix_items(stage, params):
            for entry in stage.get("params", []):
                for key in entry if isinstance(entry, dict) else [entry]:
                    for k, v in item.items():
                        key = key.replace("${item." + k + "}", str(v))
                    key = re.sub(r"\$\{([^}]+)\}", lambda m: str(OmegaConf.select(params, m.group(1))), key)
                    absent = object()  # a key may hold null (e.g. train.per_model): present all the same
                    assert OmegaConf.select(params, key, default=absent) is not absent, \
                        f"{name}{item}: params key {key} missing"


def test_stage_names_match_modules():
    stages = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]
    for name, stage in stages.items():
        assert re.search(rf"python -m toolpath\.stages\.{name}(\s|$)", stage["cmd"])
        assert (REPO / "src" / "toolpath" / "stages" / f"{name}.py").is_file()


def test_conf_avoids_constructs_that_break_dvc_composition():
    for path in (REPO / "conf").rglob("*.yaml"):
        text = path.read_text()
        assert "${hydra:" not in text and "${oc.env:" not in text, path
        assert not re.search(r"^hydra:", text, re.M), path
        assert "???" not in text, path


def test_seed_for_is_stable_and_distinct():
    assert config.seed_for(1, "generate", "gear") == config.seed_for(1, "generate", "gear")
    assert config.seed_for(1, "generate", "gear") != config.seed_for(1, "generate", "pentagram")
    assert config.seed_for(1, "label", "gear") != config.seed_for(2, "label", "gear")


def test_every_committed_bound_row_is_within_the_tolerance_both_ways():
    """Every smoothed window of the committed default-profile run, bounded modes (tube and discs), every
    method and encoding: its exact two-sided distance from the original is at most the tolerance."""
    tolerance = OmegaConf.load(REPO / "params.yaml").optimize.tolerance
    for shape in OmegaConf.load(REPO / "params.yaml").shapes:
        with (REPO / "reports" / "metrics" / "optimize" / f"{shape}.csv").open() as fh:
            bound = [r for r in csv.DictReader(fh) if r["mode"] in ("bound", "tube")]
        assert bound, shape
        for row in bound:
            assert float(row["hausdorff_mm"]) <= tolerance + 1e-9, (shape, row["window"], row["method"])


def test_every_committed_corner_is_inside_within_delta_max_and_every_plan_keeps_its_limits():
    """The committed default-profile run: every corner curve inside its corner within delta_max (two-sided),
    every plan within its limits."""
    corner = json.loads((REPO / "reports/metrics/corner.json").read_text())
    assert set(corner["cases"]) == {"w", "dress", "torch"}
    for case, record in corner["cases"].items():
        assert record["g01"]["within_limits"] and record["g01"]["bracketed"], case
        methods = record["methods"]
        for name, entry in methods.items():
            assert entry["within_limits"] and entry["bracketed"], (case, name)
            assert entry["all_inside"] and entry["max_error_mm"] <= 0.1 + 1e-9, (case, name)
    with (REPO / "reports/metrics/corner_corners.csv").open() as fh:
        for row in csv.DictReader(fh):
            if not row["source"].startswith("kept"):
                assert row["inside"] == "True" and float(row["error_mm"]) <= 0.1 + 1e-9, row
    for shape in OmegaConf.load(REPO / "params.yaml").shapes:
        planned = json.loads((REPO / f"reports/metrics/feedrate/{shape}.json").read_text())["methods"]
        for mode, by_encoding in planned.items():
            for by_method in by_encoding.values():
                for method, stats in by_method.items():
                    assert stats["all_within_limits"] and stats["all_bracketed"], (shape, mode, method)


def _names_read(sources: list[str]) -> set[str]:
    """Every name the code can read a config key by: attribute names (``cfg.x``), string constants
    (``cfg["x"]``, ``get("x")``), keyword arguments (``f(x=...)``), parameter names (``**node`` unpacked
    into a function) and dataclass / class-level annotated fields (``Settings(**node)``)."""
    import ast

    names = set()
    for source in sources:
        tree = ast.parse(source)
        docstrings = {id(n.value) for n in ast.walk(tree)
                      if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)}
        for node in ast.walk(tree):
            if id(node) in docstrings:
                continue
            if isinstance(node, ast.Attribute):
                names.add(node.attr)
            elif isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value.isidentifier():
                names.add(node.value)
            elif isinstance(node, ast.keyword) and node.arg or isinstance(node, ast.arg):
                names.add(node.arg)
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                names.add(node.target.id)
    return names


def unread_keys(params: dict, sources: list[str], dvc_yaml: str) -> list[str]:
    """Leaf keys of ``params`` no code reads: neither a name the code reads it by nor its full dotted path
    in a ``${...}`` of dvc.yaml (a section read whole by a stage, ``params: [optimize]``, counts for its keys
    only where the code also names them)."""
    names = _names_read(sources)
    referenced = set(re.findall(r"\$\{([\w.]+)\}", dvc_yaml))

    def leaves(node, path=()):
        if isinstance(node, dict):
            for key, value in node.items():
                yield from leaves(value, (*path, str(key)))
        else:
            yield path

    unread = []
    for path in leaves(params):
        if path[0] == "models" or path[-1] == "_target_" or (path[0] == "generate" and len(path) > 2):
            continue  # constructor arguments (instantiated above); drawn ranges, iterated by the synthesiser
        # a key that is no identifier (a category, "2") is an entry of a mapping read whole: its parent decides
        # and so does a model's name (train.protocol.lr.<model>)
        by_entry = not path[-1].isidentifier() or path[-1] in params.get("models", {})
        key = path[-2] if by_entry and len(path) >= 2 else path[-1]
        if key not in names and ".".join(path) not in referenced:
            unread.append(".".join(path))
    return unread


def test_no_conf_key_goes_unread():
    """Every leaf key of params.yaml is read somewhere (models.* are checked by instantiation above)."""
    params = OmegaConf.to_container(OmegaConf.load(REPO / "params.yaml"))
    sources = [f.read_text() for f in (REPO / "src/toolpath").rglob("*.py")]
    dvc_yaml = (REPO / "dvc.yaml").read_text()
    assert unread_keys(params, sources, dvc_yaml) == []
    # the check can fail: a key no code names is reported, and so is one only a comment or docstring mentions
    planted = {"optimize": {"tolerance": 0.05, "nobody_reads_this_key": 1}, "paths": {"windows": "data/windows"}}
    assert unread_keys(planted, ["cfg.optimize.tolerance  # nobody_reads_this_key", '"""nobody_reads_this_key"""'],
                       "${paths.windows}") == ["optimize.nobody_reads_this_key"]


def test_the_model_and_shape_lists_live_in_conf_and_name_what_the_code_can_build():
    """conf/ lists the shapes and models the pipeline runs (the code keeps no list of its own): every
    listed shape has an outline and a generate section, every listed model a config with a class."""
    from toolpath.models.registry import is_learned
    from toolpath.shapes.synth import OUTLINES

    params = OmegaConf.load(REPO / "params.yaml")
    assert set(params.shapes) <= set(OUTLINES) and all(shape in params.generate for shape in params.shapes)
    assert set(params.train.models) <= set(params.models)
    models = OmegaConf.to_container(params.models, resolve=True)
    # Table 4 quantizes the models on our input; Table 3a's block on the paper's input stays FP32
    assert set(params.qat.models) == {name for name in params.train.models if is_learned(models[name])
                                      and models[name]["inputs"] == "turning"}
    assert set(params.train.protocol.models) <= set(params.train.models)
    assert not is_learned(models["rule"]) and is_learned(models["mcrl"])


def test_training_settings_precedence_shape_then_model_then_shared_lr_then_common_then_tuned_schedule(tmp_path):
    """train.<shape> < train.per_model.<model> < train.common.lr < train.common < a tuned model's schedule;
    replicates differ in their seed only, replicate 0 keeps the single-run seed."""
    from toolpath.pipeline.settings import training

    listed = OmegaConf.load(config.compose([], root=REPO, output=tmp_path / "o.yaml"))
    protocol = listed.train.protocol  # the default profile: every learned model under the one protocol
    assert {"mlp", "rnn", "mcrl", "mlp_xy"} <= set(protocol.models)
    _, mcrl = training(listed, "gear", "mcrl")  # the protocol wins over the model's own schedule
    assert mcrl["epochs"] == protocol.settings.epochs and mcrl["lr"] == protocol.lr.mcrl
    assert mcrl["aux_loss_weight"] == protocol.structure.mcrl.aux_loss_weight
    # the chain below the protocol, for models it does not list
    cfg = OmegaConf.load(config.compose(["train.protocol.models=[]", "train.per_model={rnn: {epochs: 12, lr: 0.001}}"],
                                        root=REPO, output=tmp_path / "p.yaml"))
    _, mlp = training(cfg, "gear", "mlp")
    assert mlp["epochs"] == cfg.train.per_shape.gear.epochs and mlp["lr"] == cfg.train.per_shape.gear.lr
    _, rnn = training(cfg, "gear", "rnn")
    assert rnn["epochs"] == 12 and rnn["lr"] == 0.001 != cfg.train.per_shape.gear.lr
    assert rnn["clip_grad_norm"] == cfg.train.common.clip_grad_norm
    shared = OmegaConf.merge(cfg, {"train": {"common": {"lr": 0.0042}}})
    assert training(shared, "gear", "rnn")[1]["lr"] == 0.0042
    tuned = OmegaConf.merge(cfg, {"models": {"rnn": {"schedule": {"lr": 0.5, "clip_grad_norm": 9.0}}}})
    assert training(tuned, "gear", "rnn")[1]["lr"] == 0.5 and training(tuned, "gear", "rnn")[1]["clip_grad_norm"] == 9.0
    # a schedule's per_shape keys win on their shape only
    per_shape = OmegaConf.merge(tuned, {"models": {"rnn": {"schedule": {"per_shape": {"gear": {"epochs": 7}}}}}})
    assert training(per_shape, "gear", "rnn")[1]["epochs"] == 7 and training(per_shape, "gear", "rnn")[1]["lr"] == 0.5
    assert training(per_shape, "pentagram", "rnn")[1]["epochs"] == training(tuned, "pentagram", "rnn")[1]["epochs"]
    assert "per_shape" not in training(per_shape, "gear", "rnn")[1]
    seeds = [training(cfg, "gear", "mlp", r)[1] for r in range(3)]
    assert len({s["seed"] for s in seeds}) == 3 and seeds[0]["seed"] == mlp["seed"]
    assert all({k: v for k, v in s.items() if k != "seed"} == {k: v for k, v in mlp.items() if k != "seed"}
               for s in seeds)
    paper = OmegaConf.load(config.compose(["+experiment=paper"], root=REPO, output=tmp_path / "q.yaml"))
    _, rnn_paper = training(paper, "gear", "rnn")  # the paper's profile: Table 2 for every model
    assert rnn_paper["epochs"] == 497 and rnn_paper["lr"] == 1e-4 and rnn_paper["schedule"] == "step"


def test_float_modules_reads_each_models_list_and_none_for_a_model_without_one():
    from omegaconf import OmegaConf

    from toolpath.pipeline import settings

    cfg = OmegaConf.create({"qat": {"float_modules": {"cnn": ["prepare", "conv"]}}})
    assert settings.float_modules(cfg, "cnn") == ["prepare", "conv"]
    assert settings.float_modules(cfg, "mlp") == []
    assert settings.float_modules(OmegaConf.create({"qat": {"float_modules": None}}), "cnn") == []
