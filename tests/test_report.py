"""The report stage on partial inputs: cells equal their metrics, missing inputs are named.

The stage on a whole smoke pipeline (every table and figure written) is in test_pipeline.py.
"""

import json

import numpy as np
import pytest

from conftest import REPO
from toolpath.models.training.metrics import DEGENERATE
from toolpath.pipeline import config
from toolpath.reports.document import README_BEGIN, README_END, Section, replace_block
from toolpath.reports.readme import main as readme_main
from toolpath.reports.summary import table3_summary
from toolpath.reports.tables import categories_table
from toolpath.stages import report

SHAPES = ("gear", "pentagram", "maple_leaf")


def _metrics(accuracy: float) -> dict:
    confusion = [[5, 1, 0, 0], [0, 3, 0, 0], [0, 0, 2, 1], [0, 0, 0, 4]]
    test = {"accuracy": accuracy, "loss": 0.5, "precision": 0.7, "recall": 0.6, "f1": 0.65, "auc": 0.9}
    seeds = {key: {"mean": value, "sd": None, "per_seed": {"seed0": value}} for key, value in test.items()}
    return {"epochs_run": 2, "test": {**test, "confusion": confusion},
            "replicates": {"seeds": [1], "degenerate": 0, "replicates": 1, "test": seeds, "val": seeds}}


@pytest.fixture
def partial(tmp_path, monkeypatch, mlflow_store):
    """A smoke profile whose label and train metrics exist and nothing else."""
    config.compose(["+experiment=smoke", f"shapes=[{','.join(SHAPES)}]"], root=REPO, output=tmp_path / "params.yaml")
    (tmp_path / "README.md").write_text(f"# x\n\n{README_BEGIN}\nold\n{README_END}\n\nafter\n")
    for k, shape in enumerate(SHAPES):
        label = {"class_count": {"1": 60, "2": 20, "3": 15, "4": 5}, "windows": 100,
                 "class_share": {"1": 0.6, "2": 0.2, "3": 0.15, "4": 0.05}}
        path = tmp_path / "reports/metrics/label" / f"{shape}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(label))
        paired = {"mcrl": {"mlp": _paired(0.11, 0.05, 0.17)}}
        (tmp_path / "reports/metrics/compare" / shape).mkdir(parents=True, exist_ok=True)
        (tmp_path / "reports/metrics/compare" / shape / "paired.json").write_text(json.dumps(paired))
        logistic = {"turning": _metrics(0.95)["replicates"], "coordinates": _metrics(0.62)["replicates"]}
        (tmp_path / "reports/metrics/compare" / shape / "logistic.json").write_text(json.dumps(logistic))
        for model, accuracy in (("mcrl", 0.8123 + k / 100), ("mlp", 0.7), ("rule", 1.0), ("mlp_xy", 0.6)):
            path = tmp_path / "reports/metrics/train" / model / f"{shape}.json"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(_metrics(accuracy)))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_report_on_partial_inputs_names_what_is_missing_and_cells_match_metrics(partial):
    report.main([])
    text = (partial / "reports/report.md").read_text()
    assert "Profile `smoke`" in text and "Differences from the paper" in text
    # Table 3: the cell is the metric it came from (per cent, two decimals), beside the paper's
    table3 = (partial / "reports/tables/table3_metrics.md").read_text()
    assert "| mcrl | **82.23** / 94.98 (-12.75) |" in table3  # pentagram MCRL accuracy 0.8223: worse, negative
    assert "| mcrl | **81.23** / 94.75 (-13.52) |" in table3  # gear
    assert "| rule | 100.00 / - |" in table3  # the reference, never bold: the best learned model is
    assert "| logistic regression (reference) | 95.00 / - |" in table3  # in both blocks, never bold
    assert "| logistic regression (reference) | 62.00 / - |" in table3
    assert (partial / "reports/tables/table3_metrics.tex").is_file()
    table1_md = (partial / "reports/tables/table1_categories.md").read_text()
    assert "| 1 smooth | <= 1.9 | 60 (60.0 %) | 60 (60.0 %) | 60 (60.0 %) |" in table1_md
    assert (partial / "reports/figures/fig12_confusion.png").is_file()
    # sections whose inputs are absent say so, naming the file and the stage
    assert "## Table 4: inference time, FP32 and INT8\n\n**Missing section**: needs `reports/metrics/inference.json`" \
        "; run `dvc repro benchmark`." in text
    assert "`reports/metrics/optimize/gear.json`" in text and "run `dvc repro optimize`" in text
    assert "**Missing sections**: Table 2" in text  # train timing absent
    assert (partial / "README.md").read_text().count("old") == 1  # the stage never writes README.md
    assert readme_main([]) == 0  # `make readme` does, on purpose
    readme = (partial / "README.md").read_text()
    assert "old" not in readme and readme.endswith(f"{README_END}\n\nafter\n")
    assert "| gear | - | 81.2 % / 65.0 % | mcrl 81.2 % / 65.0 % | 100.0 % |" in readme


def test_the_parent_run_carries_the_headline_figures_and_the_best_model(partial):
    import mlflow

    from toolpath.pipeline import tracking

    report.main([])
    parent = mlflow.MlflowClient(tracking.tracking_uri()).search_runs(
        [tracking.experiment_id(tracking.client())], filter_string="tags.pipeline_role = 'parent'")[0]
    assert parent.data.metrics["table3.gear.mcrl.test_accuracy"] == pytest.approx(0.8123)
    # MCRL on each input and the best learned model; the others stay on their stage runs (the 60-figure cap)
    assert "table3.pentagram.mlp.test_accuracy" not in parent.data.metrics
    assert parent.data.metrics["table3.pentagram.mcrl.test_accuracy"] == pytest.approx(0.8223)
    assert parent.data.tags["best_model.gear"] == "mcrl"  # 0.81 against the MLP's 0.70; the rule is no model
    assert not any(k.startswith("smoothing.") for k in parent.data.metrics)  # absent inputs are left out


def test_report_is_byte_identical_on_rerun(partial):
    report.main([])
    first = {p: p.read_bytes() for p in (partial / "reports").rglob("*") if p.is_file()}
    report.main([])
    again = {p: p.read_bytes() for p in (partial / "reports").rglob("*") if p.is_file()}
    assert first.keys() == again.keys()
    assert [p.name for p in first if first[p] != again[p]] == []


def test_readme_without_markers_is_refused(partial, capsys):
    report.main([])
    (partial / "README.md").write_text("# no markers\n")
    assert readme_main([]) == 2
    assert "README.md: cannot write the measured figures (ValueError: README.md: report markers not found" in \
        capsys.readouterr().err
    assert (partial / "README.md").read_text() == "# no markers\n"  # untouched


def _paired(difference, low, high):
    verdict = "better" if low > 0 else "worse" if high < 0 else "no difference shown"
    figure = {"difference": difference, "low": low, "high": high, "verdict": verdict}
    return {"accuracy": figure, "f1": figure, "programs": 5, "seeds": [2, 2]}


def test_every_paired_sentence_follows_its_interval():
    """The README's and the report's comparison sentences come from the verdicts, which come from the
    intervals: above 0 better, below worse, across 0 no difference shown."""
    from toolpath.reports.summary import paired_summary
    from toolpath.reports.tables import paired_table

    paired = {"gear": {"mcrl_xy": {"cnn_xy": _paired(0.02, 0.01, 0.03), "rnn_xy": _paired(0.01, -0.01, 0.03),
                                   "lstm_xy": _paired(-0.02, -0.03, -0.01), "maxvit_xy": {"verdict": DEGENERATE}}}}
    text = paired_summary(paired)
    assert text == ("- gear, mcrl_xy: test accuracy better than cnn_xy; no difference shown against rnn_xy; "
                    "worse than lstm_xy (95 % paired interval over test programs and seeds, Table 3c).\n")
    rows = paired_table("gear", paired["gear"]).rows
    assert rows[0] == ["mcrl_xy", "cnn_xy", "+2.00 (+1.00 to +3.00)", "+2.00 (+1.00 to +3.00)", "better / better"]
    assert rows[-1] == ["mcrl_xy", "maxvit_xy", "-", "-", DEGENERATE]


def test_blocks_sections_and_summaries():
    assert replace_block(f"a\n{README_BEGIN}\nx\n{README_END}\nb", "new") == f"a\n{README_BEGIN}\nnew\n{README_END}\nb"
    missing = Section("T", missing=["f.json"], stage="s").markdown()
    assert missing == "## T\n\n**Missing section**: needs `f.json`; run `dvc repro s`.\n"
    mlp = _metrics(0.9)
    mlp["replicates"]["test"]["f1"]["mean"] = 0.95
    summary = table3_summary({"gear": {"mcrl": _metrics(0.5), "mlp": mlp}})
    assert "| gear | - | 50.0 % / 65.0 % | mlp 90.0 % / 95.0 % | - |" in summary
    shares = {"1": 0.75, "2": 0.25, "3": 0.0, "4": 0.0}
    table = categories_table({"gear": {"class_count": {"1": 3, "2": 1, "3": 0, "4": 0}, "class_share": shares,
                                       "windows": 4}}, (1.9, 3.5, 7.6))
    assert table.rows[0] == ["1 smooth", "<= 1.9", "3 (75.0 %)"] and table.rows[-1] == ["all", "", "4 (100 %)"]


def test_table5_draws_one_test_window_per_category_and_scores_each_model():
    from toolpath.geometry import local_curvature
    from toolpath.geometry.labels import categorize
    from toolpath.models.rule import LocalCurvatureRule
    from toolpath.models.training.examples import draw_per_category, predictions

    rng = np.random.default_rng(0)
    windows = rng.normal(size=(40, 50, 2)).cumsum(axis=1).astype(np.float32)
    labels = categorize(local_curvature(windows.astype(np.float64))).astype(np.int8)
    test = np.arange(40) >= 10  # the first ten are training windows: never drawn
    drawn = draw_per_category(windows, labels, test, (1, 2, 3, 4), seed=3)
    assert set(drawn) == set(np.unique(labels[test]).tolist())
    for category, window in drawn.items():
        index = int(np.flatnonzero((windows == window).all(axis=(1, 2)))[0])
        assert test[index] and labels[index] == category
    assert draw_per_category(windows, labels, test, (1, 2, 3, 4), seed=3).keys() == drawn.keys()
    rule = LocalCurvatureRule().fit(windows)
    always_one = {"one": lambda batch: np.ones(len(batch), dtype=int)}
    predicted = predictions(drawn, {"rule": rule.predict, **always_one})
    assert predicted["rule"] == {c: c for c in drawn}  # the exact rule is right on every window
    assert predicted["one"] == dict.fromkeys(drawn, 1)


def test_drawn_window_keeps_its_category_and_says_when_it_falls_back():
    from toolpath.reports.smoothing import pick_window

    rows = [{"window": str(w), "category": str(c), "baseline_window": str(b)}
            for w, c, b in ((10, 3, False), (11, 3, True), (20, 4, True), (21, 4, False))]
    assert pick_window(rows, 3, True, seed=0) == (11, 3)  # the only head-to-head window of category 3
    assert pick_window(rows, 3, False, seed=0)[1] == 3
    assert pick_window(rows, 2, True, seed=0) in {(11, 3), (20, 4)}  # no category 2: drawn elsewhere, said so
    assert pick_window([], 3, True, seed=0) is None


def test_a_model_predicting_one_class_is_shown_as_degenerate_never_scored():
    from toolpath.models.training.metrics import classification_metrics, degenerate

    y = np.array([1, 1, 1, 2, 3, 4])
    majority = classification_metrics(y, np.tile([0.7, 0.1, 0.1, 0.1], (6, 1)))
    assert degenerate(majority) and majority["accuracy"] == pytest.approx(0.5)  # the majority share
    honest = classification_metrics(y, np.eye(4)[y - 1])
    assert not degenerate(honest)


def test_program_bootstrap_hand_cases():
    from toolpath.models.training.metrics import program_bootstrap

    perfect = program_bootstrap(np.ones(30, bool), np.repeat(np.arange(6), 5), seed=0)
    assert (perfect["low"], perfect["high"], perfect["programs"]) == (1.0, 1.0, 6)
    # one program right, one wrong, equal sizes: draws give 0, 1/2 or 1
    split = program_bootstrap(np.r_[np.ones(10), np.zeros(10)], np.r_[np.zeros(10), np.ones(10)], seed=1)
    assert split["low"] == 0.0 and split["high"] == 1.0 and split["half_width"] == 0.5
    # the unit is the program: ten programs of 100 windows are wider than their windows would suggest
    rng = np.random.default_rng(2)
    per_program = rng.uniform(0.6, 1.0, 10)
    correct = np.concatenate([rng.random(100) < p for p in per_program])
    ci = program_bootstrap(correct, np.repeat(np.arange(10), 100), seed=3)
    window_half_width = 1.96 * np.sqrt(correct.mean() * (1 - correct.mean()) / len(correct))
    assert ci["low"] < correct.mean() < ci["high"] and ci["half_width"] > 1.5 * window_half_width
    assert program_bootstrap(correct, np.repeat(np.arange(10), 100), seed=3) == ci



def test_headline_names_a_corrupt_metrics_file_and_skips_an_absent_one(tmp_path):
    from toolpath.pipeline.artifacts import Layout
    from toolpath.reports.headline import headline

    layout = Layout.from_config({k: str(tmp_path / k) for k in (
        "gcode", "windows", "metrics", "models", "plots", "timing", "corpus", "smoothed", "report", "sheets",
        "sequence", "corner")})
    assert headline(layout, ["gear"], ["mcrl"]) == ({}, {})  # nothing run yet: nothing to report
    layout.train_metrics("gear", "mcrl").parent.mkdir(parents=True)
    layout.train_metrics("gear", "mcrl").write_text("{")
    with pytest.raises(SystemExit, match=r"mcrl/gear.json: not a readable JSON file .*; run `dvc repro train@mcrl`"):
        headline(layout, ["gear"], ["mcrl"])
