"""Each table builder of ``toolpath.reports`` on metrics of the committed schema with one value changed by
hand: the value must appear where it belongs, and what must be flagged (a degenerate model, limits broken,
a corner kept sharp, a ranking unlike the paper's, a colliding plan) is flagged.  The bases are the committed
default-profile metrics files, read only for their shape: every asserted figure is the one set here."""

from __future__ import annotations

import copy
import json

import pytest

from conftest import REPO
from toolpath.models.training.metrics import DEGENERATE
from toolpath.reports import corner_report, sequencing, smoothing, smoothing_tables, speed, tables

METRICS = REPO / "reports" / "metrics"
SHAPES = ("gear", "pentagram", "maple_leaf")


def load(relative: str) -> dict:
    return json.loads((REPO / "reports" / relative).read_text())


def row_of(table: tables.Table, first: str) -> list[str]:
    found = [row for row in table.rows if row[0] == first or row[0].startswith(first + " (")]
    assert found, f"no row {first!r} in {table.title!r}"
    return found[0]


# ---- classification ----------------------------------------------------------------------------------
def test_table3_shows_a_models_mean_and_flags_a_degenerate_one():
    summaries = {m: load(f"metrics/train/{m}/gear.json")["replicates"] for m in ("mcrl", "mlp", "cnn")}
    summaries["mlp"]["test"]["accuracy"]["mean"] = 0.123456
    summaries["cnn"] = copy.deepcopy(summaries["cnn"]) | {"degenerate": summaries["cnn"]["replicates"]}
    table = tables.table3("gear", summaries)
    assert row_of(table, "mlp")[1].startswith("12.35")
    assert row_of(table, "cnn")[1:1 + len(tables.TABLE3_COLUMNS)] == [DEGENERATE] * len(tables.TABLE3_COLUMNS)
    assert row_of(table, "mcrl")[1].startswith("**")  # the best scored mean is bold, the degenerate one is not
    summaries["mlp"]["test"]["accuracy"]["mean"] = 0.999
    assert row_of(tables.table3("gear", summaries), "mlp")[1].startswith("**99.90")


def test_table2_puts_the_settings_the_stage_trains_with_beside_the_papers():
    """Every number of our rows is what settings.training gives the train stage for that MCRL."""
    from omegaconf import OmegaConf

    from conftest import REPO
    from toolpath.pipeline.settings import training

    cfg = OmegaConf.load(REPO / "params.yaml")
    ours = {"gear": {m: training(cfg, "gear", m)[1] for m in ("mcrl", "mcrl_xy")}}
    ours["gear"]["mcrl"] = {**ours["gear"]["mcrl"], "schedule": "step", "patience": 3}
    runs = {"gear": {"all_seconds": 600.0, "mcrl": {"seconds": 90.0, "epochs_run": 7},
                     "mcrl_xy": {"seconds": 30.0, "epochs_run": 16}}}
    table = tables.table2("smoke", ours, runs)
    staircase, protocol = table.rows[1], table.rows[2]
    settings = ours["gear"]["mcrl"]
    assert staircase == ["gear", "profile `smoke`: mcrl", f"{settings['lr']:g}", f"{settings['decay_rate']:g}",
                         str(settings["decay_steps"]), str(settings["batch_size"]), f"7 of {settings['epochs']}",
                         "1.5 min", "10.0 min"]
    xy = ours["gear"]["mcrl_xy"]
    assert protocol[2] == f"{xy['lr']:g}" == f"{cfg.train.protocol.lr.mcrl_xy:g}"
    assert protocol[3] == "- (onecycle)" and protocol[6] == str(cfg.train.protocol.settings.epochs)
    assert protocol[7:] == ["0.5 min", "-"]
    assert "early stopping on validation loss" in table.notes[0] and "no early stopping" in table.notes[0]
    assert len(table.rows) == 3  # a shape the profile does not run has no rows


def test_corpus_table_leaves_an_origin_without_windows_blank():
    classes = {str(c): {"count": 2, "recall": 0.5 if c < 4 else None} for c in (1, 2, 3, 4)}
    entry = {"windows": 8, "rough_windows": 6, "accuracy": 0.875, "f1": 0.8, "majority_accuracy": 0.25,
             "per_class": classes}
    table = tables.corpus_table({"all": entry, "arcs": {"windows": 0}, "lines": entry})
    assert table.rows[0][:6] == ["all windows", "8", "6", "87.5", "80.0", "25.0"]
    assert table.rows[0][-1] == "0 (-)"  # no recall for a category with no window
    assert table.rows[1][1] == "0" and set(table.rows[1][2:]) == {"-"}


# ---- Table 4 -------------------------------------------------------------------------------------------
def test_table4_shows_each_variants_throughput():
    inference = load("metrics/inference.json")
    inference["models"]["mcrl"]["fp32_eager"]["windows_per_s"] = 123456.0
    table = speed.table4(inference, list(SHAPES))
    rows = [r for r in table.rows if r[0] == "mcrl"]
    assert any("123,456" in r for r in rows)
    assert table.rows[-1][0] == "rule"



def _forms(nodes: int, ratio: float, native_rate: float, shipped_rate: float = 50_000.0) -> dict:
    def row(n: int, r: float, rate: float) -> dict:
        return {"nodes": n, "recurrent_nodes": 3, "file_bytes": 1e5, "bytes_vs_checkpoint": r,
                "onnxruntime_windows_per_s": rate, "openvino_windows_per_s": rate,
                "onnxruntime_max_logit_diff": 1e-6, "openvino_max_logit_diff": 2e-6,
                "speed_vs_exporter": {"onnxruntime": rate / 40_000, "openvino": rate / 40_000}}
    return {"shipped": row(300, 1.2, shipped_rate), "exporter": row(500, 16.0, 40_000.0),
            "native": row(nodes, ratio, native_rate)}


def test_table4d_gives_each_form_and_issue_45s_targets():
    inference = {"setup": {"batch": 256}, "models": {"mcrl": {"recurrent_forms": _forms(140, 1.1, 20_000.0)},
                                                    "rnn": {"recurrent_forms": _forms(50, 1.3, 20_000.0)},
                                                    "mlp": {}}}
    table = speed.recurrent_forms(inference)
    native = {r[0]: r for r in table.rows if r[1] == "native"}
    shipped = {r[0]: r for r in table.rows if r[1] == "shipped (lean)"}
    assert len(table.rows) == 6 and set(native) == set(shipped) == {"mcrl", "rnn"}
    # 140 nodes, but 0.5x the exporter's speed; the shipped file: 1.25x, with 300 nodes
    assert native["mcrl"][-1] == "<= 150 nodes: met; ONNX Runtime >= 1.5x the exporter's unrolling: not met"
    assert shipped["mcrl"][-1] == "<= 150 nodes: not met; ONNX Runtime >= 1.5x the exporter's unrolling: not met"
    assert native["rnn"][-1].startswith("met") and "(0.50x)" in native["rnn"][5] and "(1.25x)" in shipped["rnn"][5]
    assert "shipped form was the fastest in every runtime" in table.notes[-1]
    inference["models"]["rnn"]["recurrent_forms"] = _forms(50, 1.3, 60_000.0)
    notes = speed.recurrent_forms(inference).notes
    assert "Faster than the shipped form in this run: rnn native in ONNX Runtime" in notes[-1]
    # a compact form: the nodes of its loops' bodies count toward the 150
    forms = inference["models"]["mcrl"]["recurrent_forms"]
    forms["compact"] = {**forms["native"], "nodes": 141, "loop_body_nodes": 10, "recurrent_nodes": 6}
    compact = [r for r in speed.recurrent_forms(inference).rows if r[1] == "compact (Scan loops)"]
    assert compact[0][2] == "141 + 10 in loops (6)" and compact[0][-1].startswith("<= 150 nodes: not met")
    forms["compact"]["loop_body_nodes"] = 9
    assert speed.recurrent_forms(inference).rows[3][-1].startswith("<= 150 nodes: met")
    del forms["compact"]
    inference["models"]["mcrl"]["recurrent_forms"] = _forms(140, 1.1, 20_000.0, shipped_rate=60_000.0)
    assert speed.recurrent_forms(inference).rows[0][-1].endswith("exporter's unrolling: met")
    empty = speed.recurrent_forms({"setup": {"batch": 256}, "models": {"mlp": {}}})  # the smoke profile's
    assert not empty.rows and empty.notes == [
        "Not measured in this run: `benchmark.recurrent_forms` names none of the benchmarked models."]


# ---- smoothing -----------------------------------------------------------------------------------------
def optimize_metrics() -> tuple[dict, dict]:
    return ({s: load(f"metrics/optimize/{s}.json") for s in SHAPES},
            {s: load(f"timing/optimize/{s}.json") for s in SHAPES})


def test_table6_pools_each_optimisers_reduction_over_the_shapes():
    metrics, timing = optimize_metrics()
    for shape, value in zip(SHAPES, (10.0, 20.0, 33.0), strict=True):
        metrics[shape]["head_to_head"]["tube"]["nacoa_matched"]["mean_reduction_pct"] = value
    table = smoothing_tables.table6(metrics, timing)
    nacoa = row_of(table, "NACOA (matched budget)")
    assert nacoa[table.headers.index("reduction, bound (tube) (%)")] == "21.0"  # the mean over the three shapes
    assert nacoa[table.headers.index("Fitness vectorised")] == "yes"
    assert row_of(table, "PSO")[table.headers.index("Fitness vectorised")].startswith("no")


def test_reduction_table_shows_ours_beside_the_paper_and_flags_a_ranking_unlike_the_papers():
    metrics, _ = optimize_metrics()
    stats = metrics["gear"]["methods"]["tube"]["plain"]
    stats["nacoa"]["mean_reduction_pct"], stats["bezier"]["mean_reduction_pct"] = 12.34, 50.0
    stats["mean_filter"]["mean_reduction_pct"] = 40.0
    table = smoothing.reduction_table(metrics)
    gear_bound = [r for r in table.rows if r[0] == "gear" and r[1] == "bound (tube)"][0]
    assert "12.3 (78, -65.7)" in gear_bound
    start = "gear, bound (tube), all categories, no interval: Bezier > mean filter > NACOA (not the paper's"
    assert any(n.startswith(start) for n in table.notes)
    stats["nacoa"]["mean_reduction_pct"] = 90.0
    assert any(n.startswith("gear, bound (tube)") and "as in the paper" in n
               for n in smoothing.reduction_table(metrics).notes)


def test_the_paper_metric_table_gives_intervals_and_the_sentence_they_allow():
    metrics, _ = optimize_metrics()
    pooled = metrics["gear"]["paper_metric"]["tube"]["methods"]["nacoa"]["categories_2_4"]
    pooled["mean_reduction_pct"], pooled["mean_reduction_ci"] = 70.0, [65.0, 75.0]
    table = smoothing_tables.paper_metric_table(metrics)
    nacoa = [r for r in table.rows if r[:3] == ["gear", "bound (tube)", "NACOA"]][0]
    assert nacoa[4] == "70.0 [65.0, 75.0]" and nacoa[5] == "below the paper's 78 %"
    assert any(r[2].startswith("Sec. 5.3 dispatch") for r in table.rows)


# ---- corners and feed -----------------------------------------------------------------------------------
def test_corner_cases_table_shows_each_time_and_flags_broken_limits():
    metrics = load("metrics/corner.json")
    metrics["cases"]["w"]["g01"]["within_limits"] = False
    metrics["cases"]["w"]["methods"]["nurbs_pso"]["time"] = 9.876
    table = corner_report.cases_table(metrics)
    g01 = [r for r in table.rows if r[0] == "w" and r[1] == "G01 with controller blend"][0]
    assert g01[-1] == "NO"
    assert any(r[0] == "w" and r[7] == "9.876" for r in table.rows)
    # the note names the planner's reading of a curve that the configuration chose (feedrate.band)
    assert "read point by point" in " ".join(table.notes)
    paper = " ".join(corner_report.cases_table(metrics, band=None).notes)
    assert "each sensitive interval at its lowest limit" in paper and "point by point" not in paper
    assert "varies by more than 0.1" in " ".join(corner_report.cases_table(metrics, band=0.1).notes)


def test_corners_table_marks_a_corner_kept_sharp():
    rows = [{"case": "w", "vertex": "3", "method": m, "source": source, "turn_deg": "90", "curvature_before": "2",
             "curvature_method1": "1.5", "curvature_after": "0.75", "reduction_pct": "62.5",
             "reduction_vs_method1_pct": "50", "error_mm": "0.05"}
            for m, source in (("nurbs_pso", "pso"), ("bezier", "kept"))]
    table = corner_report.corners_table(rows, "w", ["nurbs_pso", "bezier", "bspline"])
    assert table.rows == [["3", "90.0", "2.000", "1.500", "0.750 (+62.5 % / +50.0 %), error 0.050", "kept sharp",
                           "-"]]


def test_surrogate_and_pso_study_tables_show_their_counts():
    metrics = load("metrics/corner.json")
    metrics["surrogates"]["sources"]["net"] = 17
    metrics["surrogates"].update(test_corners=100, held_inside=480, train_corners=500,
                                 margin={"delta": 0.03, "wedge": 0.005})
    metrics["surrogates"]["literal"] = {**metrics["surrogates"], "sources": {"net": 6, "repaired": 90, "pso": 4,
                                                                             "infeasible": 0}}
    for case in metrics["cases"].values():
        case["methods"]["nurbs_net"]["answers"] = {"net": 2, "repaired": 1}
    table = corner_report.surrogate_table(metrics, {"pso_seconds_per_corner": 0.25})
    held, literal, cases = table.rows
    assert held[0].startswith("PSO's answers held inside (480 of 500: C(1/2) at 97 % of delta_max")
    assert held[3] == "17 (17 %)" and held[8] == "0.250" and held[9] == "-"
    assert literal[0] == "PSO's answers as found (the paper's)" and literal[3] == "6 (6 %)" and literal[8] == "-"
    n = len(metrics["cases"])
    assert cases[1] == f"{3 * n} of the case paths (other paths)" and cases[3] == f"{2 * n} ({200 / 3:.0f} %)"
    metrics["pso_study"]["cheapest_within_enough"] = None
    assert corner_report.pso_study_table(metrics).notes == []  # no size was enough: no claim


def test_windows_table_shows_time_saved_and_a_dash_where_a_method_did_not_run():
    per_shape = {s: load(f"metrics/feedrate/{s}.json") for s in SHAPES}
    per_shape["gear"]["methods"]["tube"]["plain"]["nacoa"]["time_saved_pct"] = -4.25
    del per_shape["pentagram"]["methods"]["tube"]["plain"]["nacoa"]
    row = row_of(corner_report.windows_table(per_shape, "tube"), "nacoa")
    assert row[1].startswith("-4.2 / ") and row[2] == "-"


# ---- sequencing ------------------------------------------------------------------------------------------
def test_sequencing_tables_show_travel_and_bold_only_a_collision_free_best():
    metrics, timing = load("metrics/sequence.json"), load("timing/sequence.json")
    sheet = metrics["sheets"]["58"]
    sheet["s_shaped"]["empty_travel_mm"], sheet["s_shaped"]["collisions"] = 1.0, 0
    sheet["gtsp"]["empty_travel_mm"], sheet["gtsp"]["collisions"] = 0.5, 3  # shorter, but it collides
    baselines = sequencing.baselines_table(metrics)
    assert row_of(baselines, "s_shaped")[1] == "**1 / 0**" and row_of(baselines, "gtsp")[1] == "0 / 3"
    main = sequencing.sequencing_table(metrics, timing)
    assert any(r[0] == "58" and r[1] == "yes" and r[4].startswith("1 ") for r in main.rows)
    metrics["expansion"] = {"2": {"empty_travel_mm": 1234.4, "collisions": 1}}
    assert sequencing.expansion_table(metrics, 68).rows == [["2", "1234", "1"]]


@pytest.mark.parametrize("builder", [tables.table3, smoothing.reduction_table, smoothing_tables.paper_metric_table])
def test_a_table_renders_markdown_and_latex_with_every_row(builder):
    if builder is tables.table3:
        table = builder("gear", {m: load(f"metrics/train/{m}/gear.json")["replicates"] for m in ("mcrl", "rule")})
    else:
        table = builder(optimize_metrics()[0])
    assert table.markdown().count("\n| ") == len(table.rows) + 1  # the header row and every row
    assert table.latex().count(r" \\") == len(table.rows) + 1


def test_the_training_curves_draw_every_model_on_both_inputs():
    """16 networks (8 architectures on two inputs) on one axis: one colour per architecture, the
    paper's input dashed; more models than colours never stops the report."""
    import numpy as np

    from toolpath.reports.classify_figures import curves_figure

    names = ["mcrl", "mlp", "cnn", "rnn", "lstm", "convmixer", "convnext", "maxvit", "extra1", "extra2"]
    names += [n + "_xy" for n in names]
    table = {"epoch": np.arange(1, 4), "val_accuracy": np.array([0.5, 0.7, 0.9])}
    lines = curves_figure({"gear": {n: table for n in names}}, "val_accuracy", "v").axes[0].lines
    assert len(lines) == len(names)
    style = {line.get_label(): (line.get_color(), line.get_linestyle()) for line in lines}
    assert style["cnn"][0] == style["cnn_xy"][0] and (style["cnn"][1], style["cnn_xy"][1]) == ("-", "--")
    assert style["mcrl"][0] == style["mcrl_xy"][0] == "tab:red"


def test_the_flattest_curve_bounds_the_w_reduction_by_hand():
    import math

    import pytest

    from toolpath.corners.curve import Corner, method1_at
    from toolpath.corners.pso import PsoSettings, pso_corner
    from toolpath.corners.transitions import bezier_transition

    # a square corner: the arc tangent to both legs with its middle 0.1 from the corner has radius
    # 0.1 / (sqrt 2 - 1), so curvature (sqrt 2 - 1) / 0.1
    assert corner_report.flattest_curvature(90.0, 0.1) == pytest.approx((math.sqrt(2) - 1) / 0.1, rel=1e-12)
    assert corner_report.flattest_curvature(0.0, 0.1) == 0.0  # no turn: a straight line
    # every curve we build on a corner is at least as sharp as that arc
    for turn in (40.0, 90.0, 125.4):
        corner = Corner(math.radians(turn), 2.0)
        flattest = corner_report.flattest_curvature(turn, 0.1)
        found, _ = pso_corner(corner, 0.1, settings=PsoSettings(particles=24, iterations=20, seed=3))
        bezier = bezier_transition(corner.turn, 2 * corner.leg, 0.1)
        for curve in (found, method1_at(corner, 0.1), bezier):
            assert curve is None or curve.max_curvature >= flattest * (1 - 1e-9)
    rows = [{"case": "w", "method": "nurbs_pso", "turn_deg": "90", "curvature_method1": "16.568542"},
            {"case": "w", "method": "nurbs_pso", "turn_deg": "90", "curvature_method1": "nan"},
            {"case": "w", "method": "bezier", "turn_deg": "90", "curvature_method1": "100"}]
    assert corner_report.arc_bound(rows, "w", 0.1) == pytest.approx(75.0, abs=1e-4)  # 1 - 4.1421 / 16.5685
    assert corner_report.arc_bound(rows, "dress", 0.1) is None
    metrics = load("metrics/corner.json")
    note = [n for n in corner_report.cases_table(metrics, rows, 0.1).notes if n.startswith("W:")][0]
    assert note.endswith("No curve can go beyond 75.0 % against method 1 on this path: the circular blend within "
                         "delta_max is the flattest curve inside a corner that passes within delta_max of it.")
