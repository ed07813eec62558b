"""The generate and label stage modules on the smoke profile, in a temporary directory."""

import json

import mlflow
import numpy as np
import pytest

from conftest import REPO
from toolpath import config
from toolpath.stages import generate, label


@pytest.fixture
def smoke_dir(tmp_path, monkeypatch, mlflow_store):
    config.compose(["+experiment=smoke"], root=REPO, output=tmp_path / "params.yaml")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_generate_then_label_writes_outs_metrics_and_mlflow_runs(smoke_dir):
    generate.main(["--shape", "pentagram"])
    files = sorted((smoke_dir / "data/gcode/pentagram").glob("*.nc"))
    assert len(files) == 4
    first = files[0].read_bytes()
    generate.main(["--shape", "pentagram"])  # same seed, same bytes
    assert files[0].read_bytes() == first
    label.main(["--shape", "pentagram"])
    data = np.load(smoke_dir / "data/windows/pentagram.npz")
    assert set(data.files) >= {"windows", "origin", "local_curvature", "label", "program", "first_line", "split"}
    n = len(data["label"])
    assert data["windows"].shape == (n, 50, 2) and data["windows"].dtype == np.float32
    assert set(np.unique(data["split"]).tolist()) <= {0, 1, 2}
    metrics = json.loads((smoke_dir / "reports/metrics/label/pentagram.json").read_text())
    assert metrics["windows"] == n and sum(metrics["class_count"].values()) == n
    assert set(metrics["local_curvature"]) == {"q05", "q25", "q50", "q75", "q95"}
    runs = mlflow.search_runs(experiment_names=["cnc-curvature"], output_format="list")
    names = sorted(r.info.run_name for r in runs)
    assert names.count("generate@pentagram") == 2 and "label@pentagram" in names
    parents = {r.data.tags.get("mlflow.parentRunId") for r in runs if r.info.run_name.startswith(("gen", "lab"))}
    assert len(parents) == 1 and None not in parents  # every stage run nests under one pipeline run
    child = next(r for r in runs if r.info.run_name == "label@pentagram")
    assert child.data.metrics["label/windows"] == n and child.info.status == "FINISHED"


def test_label_without_gcode_exits_with_a_message(smoke_dir):
    with pytest.raises(SystemExit, match="no G-code in"):
        label.main(["--shape", "gear"])


def test_label_names_file_and_line_of_a_malformed_program(smoke_dir):
    bad = smoke_dir / "data/gcode/gear/gear_000.nc"
    bad.parent.mkdir(parents=True)
    bad.write_text("G21\nG1 X1 Y1\nG1 X#2\n")
    with pytest.raises(SystemExit, match=r"gear_000.nc:3: '#' parameters"):
        label.main(["--shape", "gear"])
    runs = mlflow.search_runs(experiment_names=["cnc-curvature"], output_format="list")
    assert [r.info.status for r in runs if r.info.run_name == "label@gear"] == ["FAILED"]
