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
