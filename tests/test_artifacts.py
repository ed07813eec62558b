"""The typed contract between stages: every path of the layout is a declared DVC dep or out, the split
and label encodings, and one clear line for every missing or corrupt file."""

import re

import numpy as np
import pytest
import yaml
from omegaconf import OmegaConf

from conftest import REPO, write_windows
from toolpath.pipeline import artifacts
from toolpath.pipeline.artifacts import ArtifactError, Layout, Split

PARAMS = OmegaConf.load(REPO / "params.yaml")


def declared_paths() -> set[str]:
    """Every dep and out of dvc.yaml with ${paths.*}, ${item.*} and matrices expanded."""
    stages = yaml.safe_load((REPO / "dvc.yaml").read_text())["stages"]
    values = {"shapes": list(PARAMS.shapes), "train.models": list(PARAMS.train.models),
              "qat.models": list(PARAMS.qat.models)}
    found = set()
    for stage in stages.values():
        matrix = stage.get("matrix", {})
        items = [{}]
        for key, spec in matrix.items():
            choices = values[spec.strip("${}")] if isinstance(spec, str) else spec
            items = [{**i, key: c} for i in items for c in choices]
        entries = [*stage.get("deps", []), *stage.get("outs", []), *stage.get("metrics", []), *stage.get("plots", [])]
        for entry in entries:
            text = entry if isinstance(entry, str) else next(iter(entry))
            for item in items:
                path = re.sub(r"\$\{item\.(\w+)\}", lambda m, i=item: str(i[m.group(1)]), text)
                path = re.sub(r"\$\{([\w.]+)\}", lambda m: str(OmegaConf.select(PARAMS, m.group(1))), path)
                found.add(path)
    return found


def covered(path: str, declared: set[str]) -> bool:
    """``path`` is declared itself or lies inside a declared folder."""
    return any(path == d or path.startswith(d.rstrip("/") + "/") for d in declared)


def test_every_layout_path_is_a_declared_dvc_dep_or_out():
    layout, declared = Layout.from_config(PARAMS.paths), declared_paths()
    shape, model = PARAMS.shapes[0], "mcrl"
    per_shape = ("windows_file", "label_metrics", "smoothed_file", "optimize_rows", "optimize_summary",
                 "optimize_timing", "optimize_curves", "feedrate_rows", "feedrate_summary", "programs")
    paths = [getattr(layout, name)(shape) for name in per_shape]
    paths += [getattr(layout, name)(model) for name in ("fp32_dir", "int8_dir", "qat_metrics", "qat_timing")]
    paths += [layout.checkpoint(shape, model), layout.int8_model(shape, model), layout.int8_onnx(shape, model),
              layout.train_metrics(shape, model), layout.train_curves(shape, model), layout.train_timing(shape, model),
              layout.test_predictions(shape, model), layout.comparison(shape, "paired"), layout.generalised(model)]
    paths += [layout.generalise_metrics, layout.inference_metrics, layout.sequence_metrics, layout.sequence_timing,
              layout.sheet(PARAMS.sheets.counts[0]), layout.sheet_plans(PARAMS.sheets.counts[0]),
              layout.sheet_program(PARAMS.sheets.counts[0]), layout.corner_metrics, layout.corner_rows,
              layout.corner_timing, layout.corner_curves, layout.surrogates, layout.corner_profiles]
    undeclared = [str(p) for p in paths if not covered(str(p), declared)]
    assert undeclared == []


def test_split_codes_and_label_encoding():
    assert [int(s) for s in Split] == [0, 1, 2] and [s.label for s in Split] == ["train", "val", "test"]
    assert artifacts.category_index(np.array([1, 4, 2])).tolist() == [0, 3, 1]


def test_windows_round_trip_and_parts(tmp_path):
    path = write_windows(tmp_path / "gear.npz", np.arange(3 * 50 * 2).reshape(3, 50, 2), [1, 2, 4], [0, 2, 2])
    data = artifacts.load_windows(path, "gear")
    X, y = data.part(Split.TEST)
    assert y.tolist() == [2, 4] and X.shape == (2, 50, 2)
    assert set(data.parts()) == {"train", "val", "test"} and len(data.parts()["val"][1]) == 0


@pytest.mark.parametrize("content, problem", [
    (None, "windows file not found"),
    (b"PK\x03\x04 truncated", "not a readable windows file"),
    (b"", "not a readable windows file"),
])
def test_a_missing_or_corrupt_windows_file_names_the_file_and_the_stage(tmp_path, content, problem):
    path = tmp_path / "gear.npz"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(ArtifactError, match=rf"gear.npz: {problem}.*; run `dvc repro generate@gear`"):
        artifacts.load_windows(path, "gear")


def test_labels_or_splits_out_of_range_are_refused(tmp_path):
    path = write_windows(tmp_path / "gear.npz", np.zeros((2, 50, 2)), [1, 7], [0, 2])
    with pytest.raises(ArtifactError, match="labels outside 1-4"):
        artifacts.load_windows(path, "gear")


@pytest.mark.parametrize("content", [b"garbage", b"", b"PK\x03\x04", b"PK\x03\x04 truncated"])
@pytest.mark.parametrize("name, load, producer, problem", [
    ("mcrl.pt", artifacts.load_checkpoint, "train@gear-mcrl", "not a readable model file"),
    ("mlp.pt2", artifacts.load_int8, "qat@gear", "not a readable INT8 model file"),
])
def test_a_corrupt_model_file_names_the_file_and_the_stage(tmp_path, content, name, load, producer, problem):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(ArtifactError, match=rf"{name}: {problem} .*; run `dvc repro {producer}`"):
        load(path, producer)


def test_json_and_rows(tmp_path):
    artifacts.write_json({"b": float("nan"), "a": [1.0, float("inf")]}, tmp_path / "m.json")
    assert (tmp_path / "m.json").read_text() == '{\n  "a": [\n    1.0,\n    null\n  ],\n  "b": null\n}\n'
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(ArtifactError, match="bad.json: not a readable JSON file"):
        artifacts.read_json(tmp_path / "bad.json", "corner")
    artifacts.write_rows([{"x": 1 / 3, "y": "a"}], ("x", "y"), tmp_path / "r.csv")
    assert artifacts.read_rows(tmp_path / "r.csv", "corner") == [{"x": "0.333333", "y": "a"}]


def test_a_checkpoint_whose_weights_do_not_fit_its_network_is_one_line(tmp_path):
    import torch

    from toolpath.models.registry import build
    from toolpath.models.training.classifier import TorchClassifier, to_checkpoint

    clf = TorchClassifier(network={"_target_": "toolpath.models.MLP"}, settings={})
    clf.network_, clf.history_ = build(clf.network), []
    checkpoint = to_checkpoint(clf)
    checkpoint["state_dict"] = {k: torch.zeros(3) for k in checkpoint["state_dict"]}  # wrong shapes
    artifacts.save_checkpoint(checkpoint, tmp_path / "mlp.pt")
    wrong = r"mlp.pt: malformed model file \(RuntimeError.*; run `dvc repro train@gear`"
    with pytest.raises(ArtifactError, match=wrong):
        artifacts.load_classifier(tmp_path / "mlp.pt", "train@gear")
    artifacts.save_checkpoint({"network": {"_target_": "no.such.Model"}, "kind": "torch", "settings": {},
                               "state_dict": {}}, tmp_path / "odd.pt")
    with pytest.raises(ArtifactError, match=r"odd.pt: malformed model file"):
        artifacts.load_classifier(tmp_path / "odd.pt", "train@gear")


def test_a_corrupt_table_names_the_file_and_the_stage(tmp_path):
    (tmp_path / "rows.csv").write_bytes(b"a,b\n\xff\xfe,1\n")
    with pytest.raises(ArtifactError, match=r"rows.csv: not a readable CSV table .*; run `dvc repro optimize@gear`"):
        artifacts.read_rows(tmp_path / "rows.csv", "optimize@gear")
    (tmp_path / "ok.csv").write_text("a\n1\n")
    with pytest.raises(ArtifactError, match="missing column b"):
        artifacts.read_rows(tmp_path / "ok.csv", "optimize@gear", required=("a", "b"))


def test_errors_cross_a_process_pool_whole():
    """A stage's pool worker that raises one of these reaches the stage as the same one line."""
    import pickle

    from toolpath.gcode import GCodeError

    error = pickle.loads(pickle.dumps(ArtifactError("a.pt", "not a readable model file", "train@gear")))
    assert isinstance(error, ArtifactError)
    assert str(error) == "a.pt: not a readable model file; run `dvc repro train@gear`"
    line = pickle.loads(pickle.dumps(GCodeError("a.nc", 3, "bad word")))
    assert (line.source, line.line, line.message, str(line)) == ("a.nc", 3, "bad word", "a.nc:3: bad word")


def test_a_corrupt_tracking_store_is_one_line_naming_it(tmp_path, monkeypatch):
    from toolpath.pipeline import tracking

    (tmp_path / "mlflow.db").write_bytes(bytes(range(256)) * 20)
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)
    monkeypatch.setenv("DVC_ROOT", str(tmp_path))
    with pytest.raises(tracking.TrackingStoreError, match=rf"{tmp_path}/mlflow.db: not a usable MLflow store .*mv "):
        tracking.client()


def test_a_report_section_with_a_corrupt_input_names_the_file_and_the_stage(tmp_path):
    from toolpath.reports import builder

    bad = tmp_path / "m.json"
    bad.write_text("{")

    def section() -> str:
        builder.require([bad], "train@gear")
        return str(builder.read_json(bad))

    report = builder.Report.__new__(builder.Report)
    report.categories = section  # the first section of the plan reads the corrupt file
    with pytest.raises(SystemExit, match=r"m.json: not a readable JSON file .*; run `dvc repro train@gear`"):
        report.sections()


def test_the_qat_stage_exits_non_zero_when_a_model_could_not_be_quantised():
    from toolpath.inference.qat_runs import stop_if_any_failed

    report = {"gear": {"status": "ok"}, "pentagram": {"status": "failed", "reason": "x"}}
    with pytest.raises(SystemExit, match=r"qat@cnn: pentagram could not be quantised; the reasons are in m.json"):
        stop_if_any_failed(report, "qat@cnn", "m.json", "int8/cnn")
    stop_if_any_failed({"gear": {"status": "ok"}}, "qat@cnn", "m.json", "int8/cnn")


def test_qat_jobs_ship_as_tasks_of_their_own_and_keep_job_order(monkeypatch):
    """Each QAT job's ONNX export and scoring is queued as its own task when the job's QAT ends; the
    records come back in job order, whole (QAT fields and shipped fields), and a failure at either step
    is that job's failed record with its traceback."""
    from concurrent.futures import ThreadPoolExecutor

    from toolpath.inference import qat_runs

    def worker(job):
        k, onnx, fails = job
        if fails == "qat":
            return {"status": "failed", "reason": "qat"}, 0.0, "trace qat", None
        return {"status": "ok", "job": k}, float(k), None, None if onnx is None else (k, fails)

    def ship(handoff):
        k, fails = handoff
        order.append(k)
        return ({"status": "failed", "reason": "ship"}, "trace ship") if fails == "ship" else \
            ({"onnx_file_bytes": 10 * k}, None)

    order: list[int] = []
    monkeypatch.setattr(qat_runs, "worker", worker)
    monkeypatch.setattr(qat_runs, "ship", ship)
    jobs = [(0, "a.onnx", None), (1, None, None), (2, "c.onnx", "ship"), (3, "d.onnx", "qat")]
    finished = []
    with ThreadPoolExecutor(2) as pool:
        results = [None] * len(jobs)
        for k in qat_runs._finished(pool, [pool.submit(worker, job) for job in jobs], list(range(4)), results):
            finished.append(k)
    assert sorted(finished) == [0, 1, 2, 3] and sorted(order) == [0, 2]  # one ship task per job with a file
    assert results[0] == ({"status": "ok", "job": 0, "onnx_file_bytes": 0}, 0.0, None)
    assert results[1] == ({"status": "ok", "job": 1}, 1.0, None)
    assert results[2] == ({"status": "failed", "reason": "ship"}, 0.0, "trace ship")
    assert results[3] == ({"status": "failed", "reason": "qat"}, 0.0, "trace qat")
