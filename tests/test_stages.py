"""The stage modules on the smoke profile, in a temporary directory."""

import json

import mlflow
import numpy as np
import pytest

from conftest import REPO, write_windows
from toolpath.pipeline import config, tracking
from toolpath.stages import generate


@pytest.fixture
def smoke_dir(tmp_path, monkeypatch, mlflow_store):
    config.compose(["+experiment=smoke"], root=REPO, output=tmp_path / "params.yaml")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_generate_writes_programs_windows_metrics_and_mlflow_runs(smoke_dir):
    generate.main(["--shape", "maple_leaf"])
    files = sorted((smoke_dir / "data/gcode/maple_leaf").glob("*.nc"))
    assert len(files) == 4
    first, windows_file = files[0].read_bytes(), smoke_dir / "data/windows/maple_leaf.npz"
    first_windows = windows_file.read_bytes()
    generate.main(["--shape", "maple_leaf"])  # same seed, same bytes
    assert files[0].read_bytes() == first and windows_file.read_bytes() == first_windows
    data = np.load(windows_file)
    assert set(data.files) >= {"windows", "origin", "local_curvature", "label", "program", "first_line", "split"}
    n = len(data["label"])
    assert data["windows"].shape == (n, 50, 2) and data["windows"].dtype == np.float32
    assert set(np.unique(data["split"]).tolist()) <= {0, 1, 2}
    metrics = json.loads((smoke_dir / "reports/metrics/label/maple_leaf.json").read_text())
    assert metrics["windows"] == n and sum(metrics["class_count"].values()) == n
    assert set(metrics["local_curvature"]) == {"q05", "q25", "q50", "q75", "q95"}
    runs = mlflow.search_runs(experiment_names=["cnc-curvature"], output_format="list")
    names = sorted(r.info.run_name for r in runs)
    assert names.count("generate@maple_leaf") == 2
    parents = {r.data.tags.get("mlflow.parentRunId") for r in runs if r.info.run_name.startswith("gen")}
    assert len(parents) == 1 and None not in parents  # every stage run nests under one pipeline run
    child = next(r for r in runs if r.info.run_name == "generate@maple_leaf")
    assert child.data.metrics["label.windows"] == n and child.data.metrics["generate.programs"] == 4
    assert child.info.status == "FINISHED" and child.data.params["label.window"] == "50"


def test_labelling_names_file_and_line_of_a_malformed_program(smoke_dir):
    bad = smoke_dir / "data/gcode/gear/gear_000.nc"
    bad.parent.mkdir(parents=True)
    bad.write_text("G21\nG1 X1 Y1\nG1 X#<depth>\n")
    problem = r"gear_000.nc:3: word X: named parameter #<depth> is read before it is set"
    with pytest.raises(SystemExit, match=problem), tracking.stage_run("generate@gear"):
        generate.label_programs(config.load(), "gear", [bad])
    runs = mlflow.search_runs(experiment_names=["cnc-curvature"], output_format="list")
    assert [r.info.status for r in runs if r.info.run_name == "generate@gear"] == ["FAILED"]


def _trained(smoke_dir, shape, model):
    from toolpath.stages import train

    train.main(["--model", model])
    return json.loads((smoke_dir / f"reports/metrics/train/{model}/{shape}.json").read_text())


def test_train_stage_writes_metrics_curves_model_and_mlflow_epochs(smoke_dir):
    for shape in ("gear", "maple_leaf"):  # the smoke profile's shapes
        generate.main(["--shape", shape])
    metrics = _trained(smoke_dir, "maple_leaf", "mlp")
    first = (smoke_dir / "reports/metrics/train/mlp/maple_leaf.json").read_bytes()
    for split in ("val", "test"):
        assert {"accuracy", "loss", "precision", "recall", "f1", "auc", "per_class", "confusion"} <= set(metrics[split])
    assert metrics["epochs_run"] == 2
    seeds = metrics["replicates"]  # the smoke profile's 2 seeds, replicate 0's figure among them
    assert seeds["replicates"] == 2 and len(set(seeds["seeds"])) == 2
    per_seed = seeds["test"]["accuracy"]["per_seed"]
    assert per_seed["seed0"] == metrics["test"]["accuracy"]
    kept = [per_seed[f"seed{k}"] for k in range(2) if k not in seeds["degenerate_replicates"]]
    assert seeds["test"]["accuracy"]["mean"] == (pytest.approx(np.mean(kept)) if kept else None)
    windows = np.load(smoke_dir / "data/windows/maple_leaf.npz")
    test_programs = len(np.unique(windows["program"][windows["split"] == 2]))
    test_windows = int((windows["split"] == 2).sum())
    ci = metrics["test"]["accuracy_ci"]  # over the test programs, around the accuracy
    assert ci["programs"] == test_programs and ci["low"] <= metrics["test"]["accuracy"] <= ci["high"]
    assert seeds["accuracy_ci"]["programs"] == test_programs
    curves = (smoke_dir / "reports/plots/train/mlp/maple_leaf.csv").read_text().splitlines()
    assert curves[0] == "epoch,lr,train_loss,train_accuracy,val_loss,val_accuracy" and len(curves) == 3
    assert {p.name for p in (smoke_dir / "models/fp32/mlp").iterdir()} == \
        {f"{s}.{ext}" for s in ("gear", "maple_leaf") for ext in ("pt", "test.npz")}
    saved = np.load(smoke_dir / "models/fp32/mlp/maple_leaf.test.npz")  # every seed's test predictions
    assert saved["predicted"].shape == (2, test_windows) and saved["degenerate"].shape == (2,)
    client = mlflow.MlflowClient()
    run = next(r for r in mlflow.search_runs(experiment_names=["cnc-curvature"], output_format="list")
               if r.info.run_name == "train@mlp-maple_leaf")
    stage = next(r for r in mlflow.search_runs(experiment_names=["cnc-curvature"], output_format="list")
                 if r.info.run_name == "train@mlp")
    assert run.data.tags["mlflow.parentRunId"] == stage.info.run_id  # a child of the stage's run, per model
    steps = [m.step for m in client.get_metric_history(run.info.run_id, "val_accuracy")]
    assert steps == [1, 2] and run.data.metrics["test.accuracy"] == metrics["test"]["accuracy"]
    assert "confusion_test.json" in [a.path for a in client.list_artifacts(run.info.run_id)]
    _trained(smoke_dir, "maple_leaf", "mlp")  # same seed, byte-identical metrics
    assert (smoke_dir / "reports/metrics/train/mlp/maple_leaf.json").read_bytes() == first
    rule = _trained(smoke_dir, "maple_leaf", "rule")
    assert rule["test"]["accuracy"] == 1.0 and rule["epochs_run"] == 0  # the labels are the rule's
    assert rule["replicates"]["replicates"] == 1  # it learns nothing: one run


def test_train_without_windows_exits_with_a_message(smoke_dir):
    from toolpath.stages import train

    with pytest.raises(SystemExit, match="windows file not found"):
        train.main(["--model", "mlp"])
    bad = smoke_dir / "data/windows/gear.npz"
    bad.parent.mkdir(parents=True)
    np.savez(bad, windows=np.zeros((3, 50, 2)))
    with pytest.raises(SystemExit, match="missing origin, local_curvature, label, program, first_line, split"):
        train.main(["--model", "mlp"])


def test_train_refuses_windows_of_one_category(smoke_dir):
    """Bounds that put every window in one category leave nothing to learn: one line, not a 100 % model."""
    from conftest import write_windows
    from toolpath.stages import train

    write_windows(smoke_dir / "data/windows/gear.npz", np.zeros((6, 50, 2)), [1] * 6, [0, 0, 1, 1, 2, 2])
    with pytest.raises(SystemExit, match=r"gear.npz: the train split holds windows of category 1 only; check "
                                         r"label.bounds .*`dvc repro generate@gear`"):
        train.main(["--model", "mlp"])
    assert not (smoke_dir / "reports/metrics/train/mlp").exists()


def test_generalise_without_train_metrics_exits_with_a_message(smoke_dir):
    from toolpath.stages import generalise

    for shape in ("gear", "pentagram", "maple_leaf"):
        windows = smoke_dir / f"data/windows/{shape}.npz"
        windows.parent.mkdir(parents=True, exist_ok=True)
        write_windows(windows, np.zeros((2, 50, 2)), np.ones(2), np.zeros(2))
    with pytest.raises(SystemExit, match=r"train/mlp/gear.json: metrics file not found; run `dvc repro train@mlp`"):
        generalise.main([])


def test_optimize_stage_writes_rows_summary_curves_and_repeats(smoke_dir):
    import csv

    from toolpath.stages import optimize

    generate.main(["--shape", "gear"])
    optimize.main(["--shape", "gear"])
    summary_path = smoke_dir / "reports/metrics/optimize/gear.json"
    first = summary_path.read_bytes()
    summary = json.loads(first)
    with (smoke_dir / "reports/metrics/optimize/gear.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == summary["sample"]["runs"] > 0
    methods = {"mean_filter", "bezier", "nacoa", "nacoa_matched", "coa", "pso"}  # the smoke profile's methods
    assert set(summary["methods"]["tube"]["plain"]) == methods
    assert set(summary["methods"]["tube"]["shifted"]) == {"coa", "pso"}  # mealpy ones, both encodings, tube only
    assert set(summary["methods"]["none"]["plain"]) == {"mean_filter", "bezier", "nacoa"}
    for row in rows:
        if row["mode"] in ("bound", "tube"):
            assert float(row["hausdorff_mm"]) <= 0.05 + 1e-9
    assert summary["dispatch"]["tube"]["1"]["method"] == "none"
    smoothed_windows = sum(summary["sample"]["per_category"].get(c, 0) for c in ("2", "3", "4"))  # all but category 1
    assert summary["paper_metric"]["tube"]["methods"]["nacoa"]["categories_2_4"]["windows"] == smoothed_windows > 0
    curves = (smoke_dir / "reports/plots/optimize/gear.csv").read_text().splitlines()
    assert curves[0].split(",")[0] == "budget_fraction" and "nacoa" in curves[0]
    smoothed = np.load(smoke_dir / "data/smoothed/gear.npz")
    assert smoothed["points"].shape == (len(rows), 50, 2)
    timing = json.loads((smoke_dir / "reports/timing/optimize/gear.json").read_text())
    assert timing["tube"]["plain"]["nacoa"]["complexity"] == "O(n^2) + O(t p d)"
    run = next(r for r in mlflow.search_runs(experiment_names=["cnc-curvature"], output_format="list")
               if r.info.run_name == "optimize@gear")
    assert run.data.metrics["tube.plain.nacoa.all_categories_reduction_pct"] == pytest.approx(
        summary["methods"]["tube"]["plain"]["nacoa"]["mean_reduction_pct"])
    assert run.data.metrics["cat2_4_reduction_pct.tube.nacoa"] == pytest.approx(
        summary["paper_metric"]["tube"]["methods"]["nacoa"]["categories_2_4"]["mean_reduction_pct"])
    optimize.main(["--shape", "gear"])  # same seed, same bytes
    assert summary_path.read_bytes() == first


def test_optimize_rejects_an_unknown_method(smoke_dir):
    from toolpath.smoothing.runs import plan

    with pytest.raises(ValueError, match="unknown method"):
        plan([(0, 2, True)], {"methods": ["sandpaper"], "modes": ["bound"], "encodings": ["plain"]})


def test_feedrate_stage_names_a_missing_or_malformed_smoothed_file(smoke_dir):
    from toolpath.stages import feedrate

    windows = smoke_dir / "data/windows/gear.npz"
    windows.parent.mkdir(parents=True)
    write_windows(windows, np.zeros((2, 50, 2)), np.ones(2), np.full(2, 2))
    with pytest.raises(SystemExit, match=r"gear.npz: smoothed-windows file not found; run `dvc repro optimize@gear`"):
        feedrate.main(["--shape", "gear"])
    bad = smoke_dir / "data/smoothed/gear.npz"
    bad.parent.mkdir(parents=True)
    np.savez(bad, points=np.zeros((1, 50, 2)))
    with pytest.raises(SystemExit, match="malformed smoothed-windows file, missing window"):
        feedrate.main(["--shape", "gear"])


def test_feedrate_summary_totals_and_worst_cases():
    from toolpath.feedrate.windows import summarise

    rows = [{"mode": "bound", "encoding": "plain", "method": "nacoa", "time_original": t0, "time_smoothed": t1,
             "time_saved_pct": 100 * (1 - t1 / t0), "hausdorff_mm": d, "within_limits": True, "bracketed": True}
            for t0, t1, d in ((1.0, 0.5, 0.01), (3.0, 3.0, 0.04))]
    stats = summarise(rows)["bound"]["plain"]["nacoa"]
    assert stats["time_saved_pct"] == pytest.approx(100 * (1 - 3.5 / 4.0))  # of the totals, not the mean
    assert stats["mean_window_time_saved_pct"] == pytest.approx(25.0)
    assert stats["max_hausdorff_mm"] == 0.04 and stats["windows"] == 2 and stats["all_within_limits"]


def test_a_feedrate_row_is_bracketed_only_where_a_bound_was_computed():
    from toolpath.stages.feedrate import _bracketed

    assert _bracketed({"time": 1.0}, {"time": 2.0}) is None
    assert _bracketed({"bracketed": True}, {"time": 2.0}) is True
    assert _bracketed({"bracketed": True}, {"bracketed": False}) is False
