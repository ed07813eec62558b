"""conf/ is the one source of truth: params.yaml is its composition, dvc.yaml reads existing keys."""

import json
import re

import pytest
import yaml
from omegaconf import OmegaConf

from conftest import REPO
from toolpath import config


def test_params_yaml_is_the_composition_of_conf(tmp_path):
    out = config.compose([], root=REPO, output=tmp_path / "params.yaml")
    committed = (REPO / "params.yaml").read_bytes()
    assert out.read_bytes() == committed, "params.yaml drifted from conf/: run `python -m toolpath.config`"


@pytest.mark.parametrize("experiment", sorted(p.stem for p in (REPO / "conf" / "experiment").glob("*.yaml")))
def test_every_experiment_composes(tmp_path, experiment):
    cfg = OmegaConf.load(config.compose([f"+experiment={experiment}"], root=REPO, output=tmp_path / "p.yaml"))
    assert cfg.profile == experiment
    for shape in cfg.shapes:
        assert cfg.generate[shape].programs >= 1


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
    assert set(stages) >= {"generate", "label", "train"}
    for name, stage in stages.items():
        for item in _matrix_items(stage, params):
            for entry in stage.get("params", []):
                for key in entry if isinstance(entry, dict) else [entry]:
                    for k, v in item.items():
                        key = key.replace("${item." + k + "}", str(v))
                    key = re.sub(r"\$\{([^}]+)\}", lambda m: str(OmegaConf.select(params, m.group(1))), key)
                    assert OmegaConf.select(params, key) is not None, f"{name}{item}: params key {key} missing"


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


def test_committed_label_metrics_back_the_readme_claims():
    """README: on the default profile every shape has > 5,000 windows and every class > 5 % of them."""
    assert OmegaConf.load(REPO / "params.yaml").profile == "default"
    for shape in OmegaConf.load(REPO / "params.yaml").shapes:
        metrics = yaml.safe_load((REPO / "reports" / "metrics" / "label" / f"{shape}.json").read_text())
        assert metrics["windows"] > 5000, shape
        assert min(metrics["class_share"].values()) > 0.05, shape


def test_committed_optimise_metrics_back_the_readme_claims():
    """README, "Where smoothing stands": each claim checked against the committed default-profile metrics."""
    mealpy = ("coa", "hba", "avoa", "scso", "esoa", "pso")
    for shape in OmegaConf.load(REPO / "params.yaml").shapes:
        summary = json.loads((REPO / "reports" / "metrics" / "optimise" / f"{shape}.json").read_text())
        for stats in summary["methods"]["bound"].values():  # both encodings, every method
            for method in stats.values():
                assert method["max_deviation_mm"] <= 0.05 + 1e-9, shape
        none = summary["methods"]["none"]["plain"]
        assert none["nacoa"]["mean_reduction_pct"] < none["mean_filter"]["mean_reduction_pct"], shape
        for mode in ("none", "bound"):
            head = summary["head_to_head"][mode]
            best_baseline = min(head[f"{m}{e}"]["mean_fitness_after"] for m in mealpy for e in ("", "@shifted"))
            assert head["nacoa"]["mean_fitness_after"] < best_baseline, (shape, mode)
            assert head["esoa@shifted"]["mean_reduction_pct"] < head["esoa"]["mean_reduction_pct"], (shape, mode)
    deviations = [json.loads((REPO / "reports/metrics/optimise" / f"{s}.json").read_text())["methods"]["none"]["plain"]
                  ["mean_filter"]["max_deviation_mm"] for s in ("gear", "pentagram", "maple_leaf")]
    assert max(deviations) > 0.2


def test_committed_sequence_metrics_back_the_readme_claims():
    """README, "Where sequencing stands": each claim checked against the committed default-profile metrics."""
    sheets = json.loads((REPO / "reports/metrics/sequence.json").read_text())["sheets"]
    assert sorted(sheets, key=int) == [str(n) for n in OmegaConf.load(REPO / "params.yaml").sheets.counts]
    for n, row in sheets.items():
        travel = {m: s["empty_travel_mm"] for m, s in row.items()}
        assert travel["s_shaped"] < travel["manual"], n
        assert travel["s_shaped"] > travel["nearest_neighbour"], n
        assert row["s_shaped"]["collisions"] <= row["s_shaped_no_avoidance"]["collisions"], n
        assert row["gtsp_eq46"]["collisions"] == 0, n
        assert travel["gtsp_eq46"] == min(t for m, t in travel.items() if row[m]["collisions"] == 0), n
        assert travel["gtsp_eq46"] < travel["nearest_neighbour"], n
        assert travel["gtsp"] == min(travel.values()) and row["gtsp"]["collisions"] > 10, n


def test_committed_corner_and_feedrate_metrics_back_the_readme_claims():
    """README, "Where corner smoothing stands": each claim checked against the committed default-profile metrics."""
    corner = json.loads((REPO / "reports/metrics/corner.json").read_text())
    assert set(corner["cases"]) == {"w", "dress", "torch"}
    for case, record in corner["cases"].items():
        assert record["g01"]["within_limits"] and record["g01"]["bracketed"], case
        methods = record["methods"]
        for name, entry in methods.items():
            assert entry["within_limits"] and entry["bracketed"], (case, name)
            assert entry["max_error"] <= 0.1 + 1e-9, (case, name)
        pso, bspline, bezier = methods["nurbs_pso"], methods["bspline"], methods["bezier"]
        assert bspline["max_reduction_pct"] < 0 and bezier["max_reduction_pct"] < 0, case
        assert pso["max_reduction_pct"] > 0, case
        assert pso["time"] < bspline["time"], case
        assert record["g01"]["time"] < bezier["time"] < pso["time"], case
    for shape in OmegaConf.load(REPO / "params.yaml").shapes:
        planned = json.loads((REPO / f"reports/metrics/feedrate/{shape}.json").read_text())["methods"]
        for mode, by_encoding in planned.items():
            for by_method in by_encoding.values():
                for method, stats in by_method.items():
                    assert stats["all_within_limits"] and stats["all_bracketed"], (shape, mode, method)


def test_every_optimize_module_is_a_dependency_of_the_stage_it_serves():
    """optimise and corner list their modules of src/toolpath/optimize one by one: a new module must be listed."""
    deps = {d for stage in yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"].values()
            for d in stage.get("deps", []) if isinstance(d, str)}
    modules = {f"src/toolpath/optimize/{p.name}" for p in (REPO / "src/toolpath/optimize").glob("*.py")}
    assert modules <= deps, sorted(modules - deps)
