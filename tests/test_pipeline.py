"""End to end: a fresh copy of the repository, `dvc repro` on the smoke profile, `dvc metrics show`."""

import csv
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import mlflow
import numpy as np
import pytest
import yaml

from conftest import REPO, copy_store
from toolpath.gcode import read_file
from toolpath.pipeline import config

pytestmark = pytest.mark.slow
SHAPES = ("gear", "maple_leaf")  # the smoke profile's shapes


def run(cmd, cwd, env):
    done = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    assert done.returncode == 0, f"{' '.join(cmd)} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def smoke_copy(tmp_path, mlflow_template) -> tuple[Path, dict, list[str]]:
    """A git repository holding the tracked files (no outputs), composed on the smoke profile, and an empty
    MLflow store."""
    tracked = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True).stdout
    work = tmp_path / "repo"
    for rel in tracked.splitlines():
        if rel.startswith(("data/", "reports/")) or rel == "dvc.lock":
            continue  # outputs are what the run must produce
        (work / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / rel, work / rel)
    venv_bin = str(Path(sys.executable).parent)
    # one torch thread per stage: beside the other test worker on two cores, a two-thread OpenMP loop spins
    # against it (a smoke generalise stage took 90 s instead of 5)
    env = {**os.environ, "PATH": venv_bin + os.pathsep + os.environ["PATH"], "DVC_NO_ANALYTICS": "1",
           "OMP_NUM_THREADS": "1",
           "MLFLOW_TRACKING_URI": copy_store(mlflow_template, tmp_path / "mlflow.db"),
           "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@t"}
    run(["git", "init", "-q"], work, env)
    config.compose(["+experiment=smoke"], root=work)
    run(["git", "add", "-A"], work, env)
    run(["git", "commit", "-qm", "smoke"], work, env)
    return work, env, [venv_bin + "/dvc"]


@pytest.mark.xdist_group("pipeline")
def test_dvc_repro_on_smoke_profile(tmp_path, monkeypatch, mlflow_template):
    work, env, dvc = smoke_copy(tmp_path, mlflow_template)
    timing = tmp_path / "pipeline_time.json"  # `make repro`'s warm server and stage timer around `dvc repro`
    run([sys.executable, "-m", "toolpath.pipeline.warm", "--", sys.executable, "-m", "toolpath.pipeline.stage_times",
         "--out", str(timing), "--", *dvc, "repro"], work, env)
    for shape in SHAPES:
        assert (work / f"data/windows/{shape}.npz").is_file()
        metrics = json.loads((work / f"reports/metrics/label/{shape}.json").read_text())
        assert metrics["windows"] > 0
    for shape in SHAPES:
        for model in ("mcrl", "mlp", "rule"):  # the smoke profile's models
            metrics = json.loads((work / f"reports/metrics/train/{model}/{shape}.json").read_text())
            confusion = np.array(metrics["test"]["confusion"])  # the accuracy is the one its confusion gives
            assert metrics["test"]["accuracy"] == pytest.approx(np.trace(confusion) / confusion.sum())
    general = json.loads((work / "reports/metrics/generalise.json").read_text())
    assert set(general["cross_shape"]["mcrl"]) == set(SHAPES)
    real = general["real_gcode"]  # the copy has no ../shared beside it: the folder is named as missing
    assert "../shared/gcode-corpus not found" in real["skipped"]
    for shape in SHAPES:
        with (work / f"reports/metrics/optimize/{shape}.csv").open() as fh:
            bound = [r for r in csv.DictReader(fh) if r["mode"] in ("bound", "tube")]
        assert bound and max(float(r["hausdorff_mm"]) for r in bound) <= 0.05 + 1e-9
        summary = json.loads((work / f"reports/metrics/optimize/{shape}.json").read_text())
        assert summary["paper_metric"]["tube"]["methods"]["nacoa"]["categories_2_4"]["windows"] > 0
        assert summary["convergence_study"]["chosen"] in (3, 6)  # the smoke profile's candidates
    for model in ("mlp",):  # the smoke profile's QAT models
        quantized = json.loads((work / f"reports/metrics/qat/{model}.json").read_text())
        for shape in SHAPES:
            assert quantized[shape]["status"] == "ok" and quantized[shape]["reload_identical"]
            assert (work / f"models/int8/{model}/{shape}.pt2").is_file()
            for runtime in ("onnxruntime", "openvino"):  # the shipped ONNX files, scored in each runtime
                scored = quantized[shape]["runtimes"][runtime]
                assert scored["int8_agrees_with_pt2"] >= 0.9 and abs(scored["accuracy_drop_points"]) <= 5
    assert_shipped_onnx_reloads_and_agrees(work)
    inference = json.loads((work / "reports/metrics/inference.json").read_text())
    assert set(inference) == {"setup", "models", "rule", "paper_table4_s"}  # no MCRL: no branch profile
    timing_keys = {"latency_b1_ms", "s_per_batch", "windows_per_s", "windows_per_s_large_batch"}
    for model in ("mlp", "mlp_xy"):  # the smoke profile's benchmarked models
        entry = inference["models"][model]
        assert set(entry["fp32_eager"]) == timing_keys and entry["fp32_file_bytes"] > 0
        assert set(entry["test_split_s"]) == set(SHAPES)
    entry = inference["models"]["mlp"]  # the smoke profile quantizes the MLP only
    assert set(entry["int8_eager"]) == timing_keys | {"speedup_vs_fastest_fp32"} and entry["int8_file_bytes"] > 0
    assert "int8_speedup_eager" in entry
    for runtime in ("onnxruntime", "openvino"):  # every runtime, FP32 and the shipped INT8 file
        assert set(entry[f"{runtime}_int8"]) >= timing_keys and f"int8_speedup_{runtime}" in entry
    for runtime in ("onnxruntime", "openvino"):  # what each runtime spends both files' time on
        assert {p: entry["op_profile"][runtime][p]["ms_per_run"] > 0 for p in ("fp32", "int8")} == \
            {"fp32": True, "int8": True}
    best = entry["shipped"]["runtime"]
    assert best in ("onnxruntime", "openvino") or "no runtime" in entry["shipped"]["why"]
    if best is not None:  # each shape's whole split in the shipped runtime, FP32 and INT8
        assert set(entry["test_split_s"]["gear"]) == {"fp32_eager", f"{best}_fp32", f"{best}_int8", "windows"}
    unquantized = inference["models"]["mlp_xy"]
    assert "int8_missing" in unquantized and unquantized["shipped"]["runtime"] is None
    sequence = json.loads((work / "reports/metrics/sequence.json").read_text())
    assert set(sequence["sheets"]) == {"10", "14"}  # the smoke profile's sheets
    for n in ("10", "14"):
        assert sequence["sheets"][n]["manual"]["optimisation_rate_pct"] == 0.0
        program = read_file(work / f"data/sequence/sheet_{n}.nc")
        assert len(program.points) > 100
    corner = json.loads((work / "reports/metrics/corner.json").read_text())
    w = corner["cases"]["w"]  # the smoke profile's one case
    assert w["g01"]["within_limits"] and set(w["methods"]) == {"nurbs_pso", "nurbs_net", "bspline", "bezier"}
    for method in w["methods"].values():
        assert method["within_limits"] and method["all_inside"]
        assert method["max_error_mm"] is None or method["max_error_mm"] <= 0.1 + 1e-9
    assert w["methods"]["bspline"]["kept_sharp"] == w["methods"]["bezier"]["kept_sharp"] == 0
    assert corner["surrogates"]["sources"]["infeasible"] == 0
    for shape in SHAPES:
        planned = json.loads((work / f"reports/metrics/feedrate/{shape}.json").read_text())
        assert planned["methods"]["tube"]["plain"]["nacoa"]["all_within_limits"]
    report = (work / "reports/report.md").read_text()
    assert "Xie & Zhu, Table 1" in report and "NURBS corner paper, cases 1-3" in report
    # a shape outside the profile keeps its figure file (a DVC output) with the reason, and no number moves
    assert "Fig. 10: pentagram is not among this profile's shapes" in report and "fig11_maple_leaf.png" in report
    assert "Missing section" not in report and "Profile `smoke`" in report
    stems = [line.strip().removeprefix("- ${paths.report}/").split(":")[0]
             for line in (work / "dvc.yaml").read_text().splitlines() if "- ${paths.report}/" in line]
    assert stems and all((work / "reports" / stem).is_file() for stem in stems)
    assert all(f"({stem})" in report for stem in stems if stem.startswith("figures/") and stem.endswith(".png"))
    assert "Table 3 in brief" in (work / "reports/readme_block.md").read_text()
    shown = run(dvc + ["metrics", "show"], work, env)
    assert "reports/metrics/label/gear.json" in shown and "class_count.4" in shown
    assert "reports/metrics/train/mcrl/gear.json" in shown and "test.accuracy" in shown
    assert "reports/metrics/compare/gear/paired.json" in shown and "mcrl.mlp.accuracy.low" in shown
    assert "reports/metrics/optimize/gear.json" in shown
    assert "reports/metrics/qat/mlp.json" in shown and "reports/metrics/inference.json" in shown
    assert "reports/metrics/sequence.json" in shown
    assert "reports/metrics/corner.json" in shown and "reports/metrics/feedrate/gear.json" in shown
    assert_mlflow_store_reads_as_the_pipeline(work, env, json.loads(timing.read_text()))
    assert_train_outputs_in_detail(work, env)
    first_optimize = assert_optimize_outputs_in_detail(work, env)
    classified = json.loads((work / "reports/metrics/classify.json").read_text())  # Table 5, the classify stage's
    assert set(classified["predictions"]) == {"mcrl", "mlp", "rule", "mlp_xy"}
    table3 = (work / "reports/tables/table3_metrics.md").read_text()  # both input blocks, the protocol noted
    assert "**Table 3a, gear, the paper's input" in table3 and "**Table 3b, gear, our input" in table3
    assert "| mlp_xy |" in table3 and "One protocol for every learned model of this block: 2 epochs" in table3
    assert table3.count("| logistic regression (reference) |") == 2 * len(SHAPES)  # two blocks per shape
    assert "**Table 3c, gear: MCRL minus" in table3
    assert all(p == int(c) for c, p in classified["predictions"]["rule"].items())  # the exact rule is always right
    # a stage run again in its own process, as a plain `dvc repro` runs it, writes the bytes its warm run wrote
    run([sys.executable, "-m", "toolpath.stages.generate", "--shape", "maple_leaf"], work, env)
    # so every stage stays up to date (one `dvc status` for three things): after that run, after a change confined
    # to the product (toolpath smooth) and after a change of worker counts (no stage declares the resources group)
    with (work / "src/toolpath/smooth/command.py").open("a") as fh:
        fh.write("\n# a change that only the product sees\n")
    config.compose(["+experiment=smoke", "resources.workers.train=3", "resources.workers.corner=2"], root=work)
    assert yaml.safe_load((work / "params.yaml").read_text())["resources"]["workers"]["train"] == 3
    assert "up to date" in run(dvc + ["status"], work, env)
    # a change to one model's section reruns that model's stages and the stages that read every model's
    # outputs, never another model's training or QAT (`dvc status` names the stages whose own params changed;
    # the benchmark and the report follow the new checkpoint through their deps)
    config.compose(["+experiment=smoke", "models.mcrl.dropout=0.3"], root=work)
    stale = set(json.loads(run(dvc + ["status", "--json"], work, env)))
    assert stale == {"train@mcrl", "compare", "generalise"}, stale  # generalise trains MCRL on every shape
    ran = set(re.findall(r"Running stage '([^']+)'", run(dvc + ["repro", "--dry"], work, env)))
    assert "train@mcrl" in ran and not ran & {"train@mlp", "train@rule", "train@mlp_xy", "qat@mlp"}, ran
    config.compose(["+experiment=smoke", "models.mlp.hidden=[16]"], root=work)  # a quantized model: its QAT too
    assert set(json.loads(run(dvc + ["status", "--json"], work, env))) == {"train@mlp", "qat@mlp", "compare"}
    # so does a change to one model's rate in Table 3's one protocol (the report prints the rates: its params
    # change too; compare follows through its deps)
    config.compose(["+experiment=smoke", "train.protocol.lr.mlp=0.002"], root=work)
    assert set(json.loads(run(dvc + ["status", "--json"], work, env))) == {"train@mlp", "qat@mlp", "report"}
    # the optimize stage (seeded NACOA and mealpy searches) again, in this process: its warm run's bytes
    # (the optimize stage reads the seed and its own section only, which no composition above changed)
    from toolpath.stages import optimize

    monkeypatch.chdir(work)
    monkeypatch.setenv("MLFLOW_TRACKING_URI", env["MLFLOW_TRACKING_URI"])
    monkeypatch.setenv("DVC_ROOT", str(work))
    optimize.main(["--shape", "gear"])
    assert (work / "reports/metrics/optimize/gear.json").read_bytes() == first_optimize
    # and the MLP's training, on the composition the pipeline ran: its metrics to the byte
    from toolpath.stages import train

    first_train = (work / "reports/metrics/train/mlp/maple_leaf.json").read_bytes()
    config.compose(["+experiment=smoke"], root=work)
    train.main(["--model", "mlp"])
    assert (work / "reports/metrics/train/mlp/maple_leaf.json").read_bytes() == first_train


def assert_train_outputs_in_detail(work: Path, env: dict) -> None:
    """The train stage's files for one model and shape: both splits' metrics, the seeds' figures and interval
    over test programs, the curves, checkpoints and saved predictions, one MLflow run per model and shape
    under the stage's with its epochs; the exact rule right everywhere, trained once."""
    metrics = json.loads((work / "reports/metrics/train/mlp/maple_leaf.json").read_text())
    for split in ("val", "test"):
        assert {"accuracy", "loss", "precision", "recall", "f1", "auc", "per_class", "confusion"} <= set(metrics[split])
    assert metrics["epochs_run"] == 2
    seeds = metrics["replicates"]  # the smoke profile's 2 seeds, replicate 0's figure among them
    assert seeds["replicates"] == 2 and len(set(seeds["seeds"])) == 2
    per_seed = seeds["test"]["accuracy"]["per_seed"]
    assert per_seed["seed0"] == metrics["test"]["accuracy"]
    kept = [per_seed[f"seed{k}"] for k in range(2) if k not in seeds["degenerate_replicates"]]
    assert seeds["test"]["accuracy"]["mean"] == (pytest.approx(np.mean(kept)) if kept else None)
    windows = np.load(work / "data/windows/maple_leaf.npz")
    test_programs = len(np.unique(windows["program"][windows["split"] == 2]))
    test_windows = int((windows["split"] == 2).sum())
    ci = metrics["test"]["accuracy_ci"]  # over the test programs, around the accuracy
    assert ci["programs"] == test_programs and ci["low"] <= metrics["test"]["accuracy"] <= ci["high"]
    assert seeds["accuracy_ci"]["programs"] == test_programs
    curves = (work / "reports/plots/train/mlp/maple_leaf.csv").read_text().splitlines()
    assert curves[0] == "epoch,lr,train_loss,train_accuracy,val_loss,val_accuracy" and len(curves) == 3
    assert {p.name for p in (work / "models/fp32/mlp").iterdir()} == \
        {f"{s}.{ext}" for s in SHAPES for ext in ("pt", "test.npz")}
    saved = np.load(work / "models/fp32/mlp/maple_leaf.test.npz")  # every seed's test predictions
    assert saved["predicted"].shape == (2, test_windows) and saved["degenerate"].shape == (2,)
    client = mlflow.MlflowClient(tracking_uri=env["MLFLOW_TRACKING_URI"])
    runs = client.search_runs([client.get_experiment_by_name("cnc-curvature").experiment_id], max_results=1000)
    [run] = [r for r in runs if r.info.run_name == "train@mlp-maple_leaf"]
    [stage] = [r for r in runs if r.info.run_name == "train@mlp"]
    assert run.data.tags["mlflow.parentRunId"] == stage.info.run_id  # a child of the stage's run, per model
    steps = [m.step for m in client.get_metric_history(run.info.run_id, "val_accuracy")]
    assert steps == [1, 2] and run.data.metrics["test.accuracy"] == metrics["test"]["accuracy"]
    assert "confusion_test.json" in [a.path for a in client.list_artifacts(run.info.run_id)]
    rule = json.loads((work / "reports/metrics/train/rule/maple_leaf.json").read_text())
    assert rule["test"]["accuracy"] == 1.0 and rule["epochs_run"] == 0  # the labels are the rule's
    assert rule["replicates"]["replicates"] == 1  # it learns nothing: one run


def assert_optimize_outputs_in_detail(work: Path, env: dict) -> bytes:
    """The optimize stage's files for gear (rows, summary, curves, smoothed windows, timing, MLflow metrics);
    returns the summary's bytes."""
    summary_path = work / "reports/metrics/optimize/gear.json"
    first = summary_path.read_bytes()
    summary = json.loads(first)
    with (work / "reports/metrics/optimize/gear.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == summary["sample"]["runs"] > 0
    methods = {"mean_filter", "bezier", "nacoa", "nacoa_matched", "coa", "pso"}  # the smoke profile's methods
    assert set(summary["methods"]["tube"]["plain"]) == methods
    assert set(summary["methods"]["tube"]["shifted"]) == {"coa", "pso"}  # mealpy ones, both encodings, tube only
    assert set(summary["methods"]["none"]["plain"]) == {"mean_filter", "bezier", "nacoa"}
    assert summary["dispatch"]["tube"]["1"]["method"] == "none"
    smoothed_windows = sum(summary["sample"]["per_category"].get(c, 0) for c in ("2", "3", "4"))  # all but category 1
    assert summary["paper_metric"]["tube"]["methods"]["nacoa"]["categories_2_4"]["windows"] == smoothed_windows > 0
    curves = (work / "reports/plots/optimize/gear.csv").read_text().splitlines()
    assert curves[0].split(",")[0] == "budget_fraction" and "nacoa" in curves[0]
    smoothed = np.load(work / "data/smoothed/gear.npz")
    assert smoothed["points"].shape == (len(rows), 50, 2)
    timing = json.loads((work / "reports/timing/optimize/gear.json").read_text())
    assert timing["tube"]["plain"]["nacoa"]["complexity"] == "O(n^2) + O(t p d)"
    client = mlflow.MlflowClient(tracking_uri=env["MLFLOW_TRACKING_URI"])
    runs = client.search_runs([client.get_experiment_by_name("cnc-curvature").experiment_id], max_results=1000)
    [run] = [r for r in runs if r.info.run_name == "optimize@gear"]
    assert run.data.metrics["tube.plain.nacoa.all_categories_reduction_pct"] == pytest.approx(
        summary["methods"]["tube"]["plain"]["nacoa"]["mean_reduction_pct"])
    assert run.data.metrics["cat2_4_reduction_pct.tube.nacoa"] == pytest.approx(
        summary["paper_metric"]["tube"]["methods"]["nacoa"]["categories_2_4"]["mean_reduction_pct"])
    return first


def assert_mlflow_store_reads_as_the_pipeline(work: Path, env: dict, timing: dict) -> None:
    """The store of one `dvc repro` as `mlflow ui` shows it: a model-training experiment, one parent
    spanning its stages with the configuration and the report, runs that last their work (within 10 %, or 1 s, of
    the stage timer's ``timing``), every trained network a logged model, each shape's best registered
    under an alias and loadable by `toolpath smooth`."""
    import torch

    mlflow.set_tracking_uri(env["MLFLOW_TRACKING_URI"])
    client = mlflow.MlflowClient(tracking_uri=env["MLFLOW_TRACKING_URI"])
    experiment = client.get_experiment_by_name("cnc-curvature")
    assert experiment.tags["mlflow.experimentKind"] == "custom_model_development"
    runs = client.search_runs([experiment.experiment_id], max_results=1000)
    [parent] = [r for r in runs if r.data.tags.get("pipeline_role") == "parent"]
    assert parent.data.params["profile"] == "smoke" and "train.common.lr" in parent.data.params
    assert "make repro" in parent.data.tags["mlflow.note.content"]
    assert {"params.yaml", "report.md", "tables", "figures"} <= \
        {a.path for a in client.list_artifacts(parent.info.run_id)}
    assert 0 < len(parent.data.metrics) <= 60 and "table3.gear.mcrl.test_accuracy" in parent.data.metrics
    stages = [r for r in runs if r.data.tags.get("mlflow.parentRunId") == parent.info.run_id]
    assert {"generate@gear", "train@mcrl", "compare", "report"} <= {r.info.run_name for r in stages}
    assert {r.info.run_name: r.data.tags["start"] for r in stages} == {r.info.run_name: "warm" for r in stages}
    for r in stages:  # each stage's run lasts its work, and the parent spans them all
        assert r.info.status == "FINISHED" and r.info.end_time > r.info.start_time >= parent.info.start_time
        assert r.info.end_time <= parent.info.end_time
    spans = {r.info.run_name: (r.info.end_time - r.info.start_time) / 1000 for r in stages}
    assert set(spans) == set(timing["stages"])
    off = {name: (round(span, 2), timing["stages"][name]) for name, span in spans.items()
           if abs(span - timing["stages"][name]) > max(0.1 * timing["stages"][name], 1.0)}
    # 1 s at least: the timer's span starts at DVC's "Running stage" line, before DVC starts the stage's process
    # (up to 0.8 s later on a loaded machine), which a warm stage of 1.4 s can no longer hide in its 10 %
    assert not off, f"stage runs more than 10 % (1 s) off the stage timer (run s, timer s): {off}"
    assert abs((parent.info.end_time - parent.info.start_time) / 1000 - timing["total_seconds"]) \
        <= 0.1 * timing["total_seconds"]
    models = [r for r in runs if "model" in r.data.tags and r.data.tags.get("stage", "").startswith("train")]
    assert {(r.data.tags["shape"], r.data.tags["model"]) for r in models} >= {("gear", "mcrl"), ("gear", "mlp")}
    logged = mlflow.search_logged_models(experiment_ids=[experiment.experiment_id], output_format="list")
    networks = {r.info.run_id for r in models if r.data.tags["model"] != "rule"}
    assert {m.source_run_id for m in logged if m.name == "model"} == networks
    quantized = sorted(m.name for m in logged if m.name.startswith("int8-"))
    assert quantized == ["int8-mlp"] * len(SHAPES)  # the smoke QAT model
    for r in models:  # a model's run spans its training (the rule's sub-ms fit: 1 ms)
        assert r.info.end_time > r.info.start_time
    windows = np.cumsum(np.full((3, 50, 2), 0.1, np.float32), axis=1)
    for shape in SHAPES:
        version = client.get_model_version_by_alias(f"toolpath-{shape.replace('_', '-')}", "best")
        assert version.tags["model"] in ("mcrl", "mlp")
        assert version.source in {m.model_uri for m in logged if m.source_run_id == version.run_id}
    network = mlflow.pytorch.load_model("models:/toolpath-maple-leaf@best")  # one load: the same path for each
    assert network(torch.as_tensor(windows)).shape == (3, 4)
    # in this process (MLflow and torch are loaded: a new process would spend ~12 s importing them again); the
    # console script itself runs in tests/test_cli.py and .ci/core-install
    from toolpath.smooth.command import main as smooth

    old = os.environ.get("MLFLOW_TRACKING_URI")
    os.environ["MLFLOW_TRACKING_URI"] = env["MLFLOW_TRACKING_URI"]
    try:
        assert smooth([str(work / "data/gcode/gear/gear_000.nc"), "-o", str(work / "out.nc"),
                       "--classifier", "models:/toolpath-gear@best"]) == 0
    finally:
        os.environ.pop("MLFLOW_TRACKING_URI") if old is None else os.environ.__setitem__("MLFLOW_TRACKING_URI", old)
    assert (work / "out.nc").is_file()


def assert_shipped_onnx_reloads_and_agrees(work: Path) -> None:
    """The INT8 ONNX file the qat stage ships gives identical outputs when loaded again, runs in both
    runtimes, and agrees with the FP32 network on most test windows (the smoke split is easy)."""
    from toolpath.inference import runtimes
    from toolpath.pipeline import artifacts
    from toolpath.pipeline.artifacts import Split

    X = artifacts.load_windows(work / "data/windows/gear.npz", "generate@gear").part(Split.TEST)[0][:512]
    fp32 = artifacts.load_classifier(work / "models/fp32/mlp/gear.pt", "train@mlp").network_.eval()
    import torch

    with torch.inference_mode():
        expected = fp32(torch.as_tensor(X, dtype=torch.float32)).argmax(1).numpy()
    for runtime in runtimes.RUNTIMES:
        first = runtimes.logits(runtimes.runner(work / "models/int8/mlp/gear.onnx", runtime, 1), X)
        again = runtimes.logits(runtimes.runner(work / "models/int8/mlp/gear.onnx", runtime, 1), X)
        assert np.array_equal(first, again)
        assert (first.argmax(1) == expected).mean() >= 0.9


@pytest.mark.xdist_group("queue")
def test_grid_sweep_through_the_dvc_experiment_queue(tmp_path, mlflow_template):
    """Two queued experiments (a learning-rate grid), two queue workers, metrics in `dvc exp show`,
    and one MLflow parent run per experiment named after it (both workers write one SQLite store)."""
    work, env, dvc = smoke_copy(tmp_path, mlflow_template)
    # as a user queues a grid: in a workspace whose windows are made and committed, so each experiment
    # takes them from the cache and retrains only the MLP (the queue's plumbing is under test; MCRL's
    # training and export are the slow part of a whole experiment, and the smoke repro above trains it),
    # on one shape (the smoke repro above covers the three)
    config.compose(["+experiment=smoke", "shapes=[gear]"], root=work)
    run(dvc + ["repro", "generate"], work, env)
    run(["git", "add", "params.yaml", "dvc.lock"], work, env)
    run(["git", "commit", "-qm", "windows"], work, env)
    queued = run(dvc + ["exp", "run", "--queue", "-S", "+experiment=smoke", "-S", "shapes=[gear]",
                        "-S", "train.protocol.lr.mlp=1e-3,5e-4", "-S", "train.models=[mlp,rule]", "train@mlp"],
                 work, env)
    names = re.findall(r"Queued experiment '([^']+)'", queued)
    assert len(names) == 2, queued
    # the workers `dvc queue start` leaves running hold its output pipes: its output goes to a file, so the
    # call returns when it has started them
    with (tmp_path / "queue-start.log").open("w") as log:
        subprocess.run(dvc + ["queue", "start", "-j", "2"], cwd=work, env=env, stdout=log, stderr=log, check=True)
    try:
        deadline = time.monotonic() + 600
        # a worker ends when the queue is empty: until one has, nothing runs beside the experiments (a
        # `dvc queue status` is a DVC process taking the repository's lock the experiments' collection needs)
        while len(queue_workers(work)) == 2 and time.monotonic() < deadline:
            time.sleep(0.5)
        while re.search(r"\b(Queued|Running)\b", status := run(dvc + ["queue", "status"], work, env)):
            assert time.monotonic() < deadline, status
            time.sleep(5)
        run(dvc + ["queue", "stop"], work, env)
    finally:
        stop_queue_workers(work)
    assert status.count("Success") == 2, status
    ran = run(dvc + ["queue", "logs", names[0]], work, env)
    assert "Running stage 'train@mlp'" in ran and "Running stage 'generate@" not in ran, ran[-3000:]
    shown = json.loads(run(dvc + ["exp", "show", "--json"], work, env))
    tested = {rev["name"]: rev["data"]["metrics"]["reports/metrics/train/mlp/gear.json"]["data"]["test"]
              for baseline in shown for exp in baseline["experiments"] or [] for rev in exp["revs"]}
    assert set(names) <= set(tested)
    for name in names:  # each experiment's own metrics, as `dvc exp show` reads them: its accuracy is its recalls'
        classes = tested[name]["per_class"].values()
        right = sum((c.get("recall") or 0.0) * c.get("support", 0) for c in classes)
        assert tested[name]["accuracy"] == pytest.approx(right / sum(c.get("support", 0) for c in classes))
        assert tested[name]["windows"] == sum(c.get("support", 0) for c in classes)
    lrs = {rev["name"]: rev["data"]["params"]["params.yaml"]["data"]["train"]["protocol"]["lr"]["mlp"]
           for baseline in shown for exp in baseline["experiments"] or [] for rev in exp["revs"]}
    assert sorted(lrs[n] for n in names) == [5e-4, 1e-3]
    # each trained at its own rate (the rate changes the result), on the windows the workspace committed
    assert tested[names[0]]["accuracy"] != tested[names[1]]["accuracy"] or \
        tested[names[0]]["loss"] != tested[names[1]]["loss"]
    client = mlflow.MlflowClient(tracking_uri=env["MLFLOW_TRACKING_URI"])
    runs = client.search_runs([client.get_experiment_by_name("cnc-curvature").experiment_id])
    parents = {r.info.run_name: r.info.run_id for r in runs if r.data.tags.get("pipeline_role") == "parent"}
    assert set(names) <= set(parents)
    for name in names:
        children = [r.info.run_name for r in runs if r.data.tags.get("mlflow.parentRunId") == parents[name]]
        assert "train@mlp" in children


def queue_workers(work: Path) -> list[int]:
    """The queue's worker processes still running (their pid files under .dvc/tmp/exps/celery)."""
    pids = []
    for pid_file in (work / ".dvc/tmp/exps/celery").glob("*.pid"):
        try:
            pids.append(int(pid_file.read_text().strip()))
        except (OSError, ValueError):
            continue
    return [pid for pid in pids if _alive(pid)]


def stop_queue_workers(work: Path, grace: float = 15.0) -> None:
    """End the queue's workers that `dvc queue stop` left running: a worker whose idle monitor stopped while
    its task ran was once seen waiting for ever after the task succeeded (dvc-task), which held the test."""
    deadline = time.monotonic() + grace
    for pid in queue_workers(work):
        while _alive(pid) and time.monotonic() < deadline:
            time.sleep(0.2)
        if _alive(pid):
            os.kill(pid, 15)


def _alive(pid: int) -> bool:
    """Whether ``pid`` is still a running queue worker (not gone, not a zombie, not a reused pid)."""
    try:
        command = Path(f"/proc/{pid}/cmdline").read_bytes()
        state = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    return b"queue-worker" in command and "zombie" not in state.lower()

