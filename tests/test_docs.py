"""README.md and docs/ say what the code and the committed measurements say:

* README's generated blocks (the report's summary, the pipeline's time, the G-code speeds) are what
  ``make readme`` writes from the committed files: a block typed by hand, or left stale after a rerun, fails;
* every ``toolpath.*`` name the docs mention exists (a module, or a name in one), and every ``python -m``
  command they show names a module that exists;
* the layout the README draws names the packages that are there.
"""

from __future__ import annotations

import re

import pytest

from conftest import REPO
from toolpath.reports import readme
from toolpath.reports.document import replace_block

DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def test_readmes_measured_figures_are_the_committed_files():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    for name, block in readme.blocks(REPO).items():
        assert replace_block(text, block, marker=name) == text, f"README's {name} block is stale: run `make readme`"


def test_the_time_block_names_every_family_and_the_total():
    timing = {"total_seconds": 1500.4, "families": {"train": 900.0, "qat": 600.4}}
    assert readme.time_block(timing).startswith("The last measured `dvc repro` of the default profile took 25.0 "
                                                "minutes (1500 s; by stage family: train 900 s, qat 600 s)")
    stopped = {**timing, "exit_code": 255, "stages": {"train@gear": 900.0, "report": 5.0}}
    assert readme.time_block(stopped).startswith("The last measured `dvc repro` of the default profile stopped with "
                                                 "exit code 255 in stage `report` after 25.0 minutes")
    measured = {**timing, "dvc_seconds": 41.6}  # stage_times counts DVC's work between stages apart
    assert "qat 600 s, DVC's own work between stages 42 s)" in readme.time_block(measured)
    # a family DVC found up to date is named, not silently missing from the total
    assert readme.time_block(timing, ("train", "qat")).endswith("`reports/pipeline_time.json`.")
    assert readme.time_block(timing, ("train", "qat", "classify", "feedrate")).endswith(
        " `classify` and `feedrate` were up to date (inputs unchanged since the committed results) and did not "
        "re-run, so they are not in this figure.")


def test_a_changed_source_makes_the_block_differ(tmp_path):
    for name in ("reports/readme_block.md", "reports/pipeline_time.json", "reports/bench/gcode.json"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes((REPO / name).read_bytes())
    timing = tmp_path / "reports/pipeline_time.json"
    timing.write_text(timing.read_text().replace('"total_seconds": ', '"total_seconds": 1'))
    text = (REPO / "README.md").read_text(encoding="utf-8")
    assert replace_block(text, readme.blocks(tmp_path)["time"], marker="time") != text


def _module_file(dotted: str):
    path = REPO / "src" / dotted.replace(".", "/")
    for candidate in (path / "__init__.py", path.with_suffix(".py")):
        if candidate.is_file():
            return candidate
    return None


def _exists(dotted: str) -> bool:
    """A module under src/, or a name its longest module prefix defines (def, class or assignment)."""
    parts = dotted.rstrip(".").split(".")
    for cut in range(len(parts), 0, -1):
        found = _module_file(".".join(parts[:cut]))
        if found is None:
            continue
        if cut == len(parts):
            return True
        text = found.read_text(encoding="utf-8")
        if found.name == "__init__.py" and re.search(rf"[\"']{parts[cut]}[\"']", text):
            return True  # a name the package loads on first use (PEP 562)
        return bool(re.search(rf"^\s*(def|class) {parts[cut]}\b|^{parts[cut]}\b\s*[:=]|import .*\b{parts[cut]}\b",
                              text, re.M))
    return False


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_toolpath_name_in_the_docs_exists(doc):
    names = set(re.findall(r"`(toolpath(?:\.\w+)+)", doc.read_text(encoding="utf-8")))
    names |= set(re.findall(r"python -m (toolpath(?:\.\w+)*)", doc.read_text(encoding="utf-8")))
    missing = sorted(n for n in names if not _exists(n))
    assert not missing, f"{doc.name} names what the code does not have: {missing}"


def test_the_readme_layout_lists_every_package():
    layout = (REPO / "README.md").read_text(encoding="utf-8").split("## Layout", 1)[1]
    packages = sorted(p.parent.name for p in (REPO / "src" / "toolpath").glob("*/__init__.py"))
    assert [p for p in packages if f"{p}/" not in layout] == []


def test_the_test_program_counts_in_methods_md_are_the_label_metrics():
    """docs/methods.md gives each shape's test programs by hand: they must be the committed label metrics'."""
    import json

    found = re.search(r"test programs \((\d+) / (\d+) / (\d+)\s+on gear / pentagram / maple leaf\)",
                      (REPO / "docs/methods.md").read_text(encoding="utf-8"))
    assert found, "docs/methods.md no longer states the test programs per shape"
    counts = [json.loads((REPO / f"reports/metrics/label/{s}.json").read_text())["split_programs"]["test"]
              for s in ("gear", "pentagram", "maple_leaf")]
    assert [int(g) for g in found.groups()] == counts


def test_the_methods_page_gives_the_surrogates_draw_and_margin_of_the_default_profile():
    import yaml

    text = " ".join((REPO / "docs" / "methods.md").read_text(encoding="utf-8").split())
    data = yaml.safe_load((REPO / "params.yaml").read_text(encoding="utf-8"))["corner"]["dataset"]
    turns, legs, margin = data["turns_deg"], data["legs"], data["margin"]
    assert f"trained in the stage on {data['train']:,} drawn corners" in text
    assert f"tested on {data['test']} drawn apart" in text
    assert f"turns {turns[0]:g}-{turns[1]:g} deg, legs {legs[0]:g}-{legs[1]:g} mm" in text
    assert f"C(1/2) at {100 * (1 - margin['delta']):g} % of delta_max" in text
    assert f"the extra point {100 * margin['wedge']:g} % of L into the corner" in text


def test_the_methods_page_orders_the_corner_paths_as_the_planner_bench_measured():
    """What docs/methods.md says of the corner cases' machining times follows reports/bench/planner_limit.json."""
    import json

    text = " ".join((REPO / "docs" / "methods.md").read_text(encoding="utf-8").split())
    by_rate = json.loads((REPO / "reports/bench/planner_limit.json").read_text())["by_tangential_acceleration"]
    configured, *higher = (by_rate[rate] for rate in sorted(by_rate, key=float))  # the configured rate is the lowest
    gaps = [row["pointwise_without_jerk_limit_over_bound_pct"]
            for rows in by_rate.values() for paths in rows.values() for row in paths.values()]
    assert "meets toppra's bound on every case path" in text and max(abs(g) for g in gaps) < 0.5
    rule_cost = {method: [paths[method]["planner"] / paths[method]["pointwise"] - 1 for paths in configured.values()]
                 for method in ("nurbs_pso", "bezier", "bspline")}
    assert "costs NURBS + PSO and the dual Bezier almost nothing and the cubic B-spline" in text
    assert max(map(abs, rule_cost["nurbs_pso"] + rule_cost["bezier"])) < 0.005 < 0.05 < max(rule_cost["bspline"])
    names = {"w": "W", "dress": "dress", "torch": "torch"}
    slower = [names[c] for c in names if configured[c]["nurbs_pso"]["saved_vs_g01_pct"]["toppra_bound"] < 0]
    assert f"is the faster on {' and '.join(slower)}," in text
    assert all(paths["nurbs_pso"]["saved_vs_g01_pct"]["toppra_bound"] < 0 for rows in higher for paths in rows.values())
    assert "and at 2.5x and 5x the tangential acceleration on all three cases" in text


def test_readmes_warm_start_figures_are_the_committed_bench():
    import json

    bench = json.loads((REPO / "reports/bench/warm_start.json").read_text(encoding="utf-8"))
    text = " ".join((REPO / "README.md").read_text(encoding="utf-8").split())
    assert f"{bench['saved_s_per_stage']:.1f} s of a small stage's {bench['cold_median_s']:.1f} s" in text
    assert f"MCRL training steps: {bench['training_steps']['forked_vs_spawned']:.2f}x the time" in text
