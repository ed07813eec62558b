"""The report's sections: Tables 1-6 and Figures 6-11 of Li et al. beside ours, then Xie & Zhu's and
the NURBS corner paper's results (Tables 7-15, Figures 12-17).  Reads only DVC outputs (at the paths
of :class:`Layout`, through the artifacts' readers) and the composed parameters; each table and figure
is written as it is built.  A section whose inputs are missing is kept as "missing", naming the files
and the stage that makes them."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from toolpath.pipeline import artifacts
from toolpath.pipeline.artifacts import Layout, load_arrays, load_smoothed, load_windows
from toolpath.pipeline.seeds import seed_for
from toolpath.reports import (
    classify_figures,
    corner_report,
    ranking,
    sequencing,
    smoothing,
    smoothing_tables,
    summary,
)
from toolpath.reports.document import Section
from toolpath.reports.paper import PAPER_SHAPE_FIGURES, TABLE5_CORRECT
from toolpath.reports.speed import int8_gains, int8_profile, recurrent_forms, table4
from toolpath.reports.tables import (
    INPUT_BLOCKS,
    LOGISTIC,
    Table,
    categories_table,
    corpus_table,
    paired_table,
    table2,
    table3,
)


def protocol_note(cfg, block: Iterable[str]) -> str | None:
    """A Table 3 block's note: the one protocol its models (``block``) trained under (``train.protocol``),
    from the config; None when the protocol lists none of them."""
    protocol = OmegaConf.to_container(cfg.train.get("protocol") or {}, resolve=True)
    listed = [m for m in protocol.get("models") or [] if m in set(block)]
    if not listed:
        return None
    settings = protocol.get("settings") or {}
    common = cfg.train.common
    rates = ", ".join(f"{m} {protocol['lr'][m]:g}" for m in listed)
    return (f"One protocol for every learned model of this block: {settings.get('epochs')} epochs, "
            f"{common.schedule} schedule (warm-up {common.warmup:g}), augmentation "
            f"{'on' if settings.get('augment', common.augment) else 'off'}, class weights "
            f"{common.class_weight or 'none'}, auxiliary losses weight {settings.get('aux_loss_weight', 0):g}, "
            f"batch {settings.get('batch_size')}; each model's learning rate chosen from the grid "
            f"{', '.join(f'{r:g}' for r in protocol['tune']['lr'])} by validation macro F1 on "
            f"{protocol['tune']['shape']}'s validation programs, one seed (`python -m toolpath.sweep.protocol`, "
            f"reports/tuning/protocol.md; the test split is never read): {rates}." + "".join(
                f" {m}'s own structure, tried at every rate in the same study and chosen there: "
                + ", ".join(f"{k} {v:g}" for k, v in option.items()) + "."
                for m, option in (protocol.get("structure") or {}).items() if m in listed))


class Missing(Exception):
    """Inputs a section needs that are not there."""

    def __init__(self, paths: list[Path], stage: str) -> None:
        super().__init__(", ".join(map(str, paths)))
        self.paths, self.stage = paths, stage


_required_by: list[str] = [""]  # the stage whose files the section being built asked for last


def require(paths: list[Path], stage: str) -> None:
    _required_by[0] = stage
    absent = [p for p in paths if not p.exists()]
    if absent:
        raise Missing(absent, stage)


def read_json(path: Path) -> dict:
    """A metrics file through the artifacts' reader: a corrupt one stops naming the stage to rerun."""
    return artifacts.read_json(path, _required_by[0])


def read_csv(path: Path) -> list[dict]:
    return artifacts.read_rows(path, _required_by[0])


def read_columns(path: Path) -> dict[str, np.ndarray]:
    rows = read_csv(path)
    try:
        return {k: np.array([float(r[k]) for r in rows]) for k in (rows[0] if rows else {})}
    except (TypeError, ValueError) as exc:
        raise artifacts.ArtifactError(path, f"a column is not numeric ({exc})", _required_by[0]) from None


class Report:
    """Builds the sections, writing each table and figure as it goes."""

    def __init__(self, cfg, layout: Layout, out: Path,
                 training: Callable[[str, str], dict] | None = None) -> None:
        """``training(shape, model)``: the settings the train stage trained that model with (Table 2)."""
        self.cfg, self.layout, self.out = cfg, layout, out
        self.training = training
        self.shapes = list(cfg.shapes)
        self.learned = [m for m in cfg.train.models if m != "rule"]
        self.written: list[Path] = []
        self.summaries: dict[str, str] = {}

    def table(self, table: Table | list[Table], stem: str) -> str:
        tables = table if isinstance(table, list) else [table]
        base = self.out / "tables" / stem
        base.parent.mkdir(parents=True, exist_ok=True)
        md = "\n".join(t.markdown() for t in tables)
        base.with_suffix(".md").write_text(md, encoding="utf-8")
        base.with_suffix(".tex").write_text("\n".join(t.latex() for t in tables), encoding="utf-8")
        self.written += [base.with_suffix(".md"), base.with_suffix(".tex")]
        return md

    def figure(self, fig, stem: str, caption: str) -> str:
        self.written += classify_figures.save(fig, self.out / "figures" / stem)
        return f"![{caption}](figures/{stem}.png)\n\n*{caption}* ([PDF](figures/{stem}.pdf))\n"

    # ---- classification -------------------------------------------------------------------
    def categories(self) -> str:
        files = {s: self.layout.label_metrics(s) for s in self.shapes}
        require(list(files.values()), "label")
        return self.table(categories_table({s: read_json(p) for s, p in files.items()}, tuple(self.cfg.label.bounds)),
                          "table1_categories")

    def train_metrics(self) -> dict[str, dict[str, dict]]:
        files = {(s, m): self.layout.train_metrics(s, m) for s in self.shapes for m in self.cfg.train.models}
        require(list(files.values()), "train")
        return {s: {m: read_json(files[(s, m)]) for m in self.cfg.train.models} for s in self.shapes}

    def hyperparameters(self) -> str:
        metrics = self.train_metrics()
        timing = {(s, m): self.layout.train_timing(s, m) for s in self.shapes for m in self.learned}
        require(list(timing.values()), "train")
        anchors = [m for m in self.learned if self.cfg.models[m]["_target_"] == "toolpath.models.MCRL"]
        runs = {}
        for s in self.shapes:
            seconds = {m: sum(read_json(timing[(s, m)])["train_seconds"]) for m in self.learned}  # over the seeds
            runs[s] = {"all_seconds": sum(seconds.values()),
                       **{m: {"seconds": seconds[m], "epochs_run": metrics[s][m]["epochs_run"]} for m in anchors}}
        if self.training is None:
            raise ValueError("Report(training=...) is needed for Table 2: the settings each MCRL trained with")
        ours = {s: {m: self.training(s, m) for m in anchors} for s in self.shapes}
        return self.table(table2(self.cfg.profile, ours, runs), "table2_hyperparameters")

    def performance(self) -> str:
        metrics = self.train_metrics()
        inputs = {m: self.cfg.models[m].get("inputs", "turning") for m in self.learned}
        logistic_files = {s: self.layout.comparison(s, "logistic") for s in self.shapes}
        require(list(logistic_files.values()), "compare")
        logistic = {s: read_json(p) for s, p in logistic_files.items()}
        def rows(shape: str, block: str) -> dict:
            own = {m: metrics[shape][m]["replicates"] for m in metrics[shape] if m == "rule" or inputs[m] == block}
            return {**own, **({LOGISTIC: logistic[shape][block]} if block in logistic[shape] else {})}

        notes = {block: protocol_note(self.cfg, [m for m in self.learned if inputs[m] == block])
                 for block in INPUT_BLOCKS}
        tables = [table3(s, rows(s, block), block, notes[block])
                  for s in self.shapes for block in INPUT_BLOCKS if block in inputs.values()]
        paired_files = {s: self.layout.comparison(s, "paired") for s in self.shapes}
        require(list(paired_files.values()), "compare")
        paired = {s: read_json(p) for s, p in paired_files.items()}
        tables += [paired_table(s, paired[s]) for s in self.shapes if paired[s]]
        self.summaries["table3"] = summary.table3_summary(metrics)
        self.summaries["paired"] = summary.paired_summary(paired)
        text = self.table(tables, "table3_metrics")
        blocks, dropped = ranking.accuracy_blocks(metrics, self.learned)
        result = ranking.rank(blocks)
        text += "\n" + self.table(ranking.ranking_table(result, blocks, dropped), "table3_ranking")
        return text + "\n" + self.figure(ranking.cd_figure(result), "table3_ranking_cd",
                                         "Critical-difference diagram of Table 3d: networks joined by a bar are not "
                                         "shown to differ (Nemenyi, alpha 0.05)")

    def curves(self) -> str:
        files = {(s, m): self.layout.train_curves(s, m) for s in self.shapes for m in self.learned}
        require(list(files.values()), "train")
        curves = {s: {m: read_columns(files[(s, m)]) for m in self.learned} for s in self.shapes}
        accuracy = classify_figures.curves_figure(curves, "val_accuracy", "validation accuracy")
        loss = classify_figures.curves_figure(curves, "val_loss", "validation loss (Eq. 29)")
        return (self.figure(accuracy, "fig6_accuracy", "Fig. 6: validation accuracy per epoch, every model, MCRL red")
                + "\n" + self.figure(loss, "fig7_loss", "Fig. 7: validation loss per epoch, every model, MCRL red"))

    def confusion(self) -> str:
        model = self.cfg.report.confusion_model
        metrics = self.train_metrics()
        confusions = {s: np.array(metrics[s][model]["test"]["confusion"]) for s in self.shapes}
        return self.figure(classify_figures.confusion_panels(confusions, model), "fig12_confusion",
                           f"Ours: {model} confusion matrices on each shape's test programs (rows: true category)")

    def cross_shape(self) -> str:
        path = self.layout.generalise_metrics
        require([path], "generalise")
        data = read_json(path)
        best = data.get("best_baseline", "-")
        parts = [self.figure(classify_figures.cross_shape_figure(data["cross_shape"]), "fig13_cross_shape",
                             f"Ours: {self.cfg.generalise.model} and the best baseline by validation accuracy "
                             f"({best}), each trained on one shape and tested on each")]
        real = data.get("real_gcode", {})
        if "metrics" in real:
            parts.append(f"MCRL trained on all three shapes, on the real G-code of the corpus (labelled by the rule): "
                         f"accuracy {real['metrics']['accuracy']:.3f}, macro F1 {real['metrics']['f1']:.3f}, "
                         f"majority-class accuracy {real['majority_accuracy']:.3f}.\n")
            if "by_origin" in real:
                parts.append(self.table(corpus_table(real["by_origin"]), "table15_real_gcode"))
        elif "skipped" in real:
            parts.append(f"Real G-code: {real['skipped']}.\n")
        return "\n".join(parts)

    def inference(self) -> str:
        path = self.layout.inference_metrics
        qat_paths = {m: self.layout.qat_metrics(m) for m in self.cfg.qat.models}
        require([path], "benchmark")
        require(list(qat_paths.values()), "qat")
        inference = read_json(path)
        quantized = {m: read_json(p) for m, p in qat_paths.items()}  # per model, keyed by shape
        by_shape = {s: {m: entries[s] for m, entries in quantized.items() if s in entries} for s in self.shapes}
        return self.table([table4(inference, self.shapes), int8_gains(inference, by_shape),
                           int8_profile(inference), recurrent_forms(inference)], "table4_inference")

    def classification(self) -> str:
        path = self.layout.classify_metrics
        require([path], "classify")
        data = read_json(path)
        drawn = {int(c): np.array(w) for c, w in data["windows"].items()}
        # in the configuration's model order (the file's keys are sorted)
        order = [m for m in self.cfg.train.models if m in data["predictions"]]
        predictions = {m: {int(c): int(p) for c, p in data["predictions"][m].items()} for m in order}
        table = Table(f"Table 5: one seeded random test window per category ({data['shape']}), each model's "
                      "prediction", ["model", *(f"category {c}" for c in drawn), "correct (paper)"])
        for model, predicted in predictions.items():
            right = sum(predicted[c] == c for c in drawn)
            table.add([model, *("correct" if predicted[c] == c else f"wrong ({predicted[c]})" for c in drawn),
                       f"{right} / {len(drawn)} ({TABLE5_CORRECT[model]} / 4)" if model in TABLE5_CORRECT
                       else f"{right} / {len(drawn)} (-)"])
        table.notes.append("The paper: MCRL right on all four, every other model wrong on one (which is not stated). "
                           "Four windows are an anecdote; Table 3 is the measurement.")
        return self.table(table, "table5_classification") + "\n" + self.figure(
            classify_figures.classification_grid(drawn, predictions), "table5_classification",
            "Table 5 as the paper draws it: green where the model predicts the window's category, red where not")

    # ---- smoothing ------------------------------------------------------------------------
    def optimize_inputs(self) -> dict[str, dict]:
        lay = self.layout
        files = {s: {"metrics": lay.optimize_summary(s), "rows": lay.optimize_rows(s), "timing": lay.optimize_timing(s),
                     "smoothed": lay.smoothed_file(s), "windows": lay.windows_file(s)} for s in self.shapes}
        require([p for f in files.values() for p in f.values()], "optimize")
        out = {}
        for s, f in files.items():
            smoothed = load_smoothed(f["smoothed"], s)
            out[s] = {"metrics": read_json(f["metrics"]), "rows": read_csv(f["rows"]),
                      "timing": read_json(f["timing"]), "smoothed": vars(smoothed),
                      "windows": load_windows(f["windows"], s).windows.astype(np.float64)}
        return out

    def optimisers(self) -> str:
        data = self.optimize_inputs()
        metrics = {s: d["metrics"] for s, d in data.items()}
        self.summaries["table6"] = summary.table6_summary(metrics)
        table6 = smoothing_tables.table6(metrics, {s: d["timing"] for s, d in data.items()})
        return (self.table(smoothing_tables.paper_metric_table(metrics), "table6_reduction") + "\n"
                + self.table(table6, "table6_optimisers") + "\n"
                + self.table(smoothing_tables.study_table(metrics), "table6_nacoa_study") + "\n"
                + self.table(smoothing.reduction_table(metrics), "table6_reduction_all_categories"))

    def smoothing_figures(self) -> str:
        data = self.optimize_inputs()
        rcfg, seed = self.cfg.report, seed_for(self.cfg.seed, "report", "figures")
        mode, parts, cases, drawn = rcfg.figures_mode, [], {}, []
        # a window the figures' mode ran on (a mode may run on only the first windows of each category)
        in_mode = {s: [r for r in d["rows"] if r["mode"] == mode] for s, d in data.items()}
        for s, d in data.items():
            picked = smoothing.pick_window(in_mode[s], rcfg.figure_category, True, seed)
            if picked is not None:
                head, category = picked
                drawn.append(f"{s} window {head}, category {category}")
                methods = sorted({r["method"] for r in d["rows"] if int(r["window"]) == head})
                cases[s] = (d["windows"][head], smoothing.window_results(d["smoothed"], head, methods, mode))
        if cases:
            parts.append(self.figure(smoothing.methods_figure(cases, mode), "fig8_methods",
                                     "Fig. 8: one drawn window per shape (" + "; ".join(drawn)
                                     + "), the original (black) and every method"))
        for s, number in PAPER_SHAPE_FIGURES.items():  # a shape keeps its number, in any profile
            picked = None if s not in data else smoothing.pick_window(in_mode[s], rcfg.figure_category, False, seed)
            if picked is None:
                why = (f"{s} is not among this profile's shapes" if s not in data
                       else f"no smoothed {s} window in the sample")
                parts.append(self.figure(smoothing.notice_figure(f"Fig. {number}: {why}."), f"fig{number}_{s}",
                                         f"Fig. {number}: {why}"))
                continue
            window, category = picked
            d = data[s]
            stats = d["metrics"]["methods"][mode]["plain"]
            results = smoothing.window_results(d["smoothed"], window, smoothing.PAPER_METHODS, mode)
            mean = {m: stats[m]["mean_reduction_pct"] for m in results}
            parts.append(self.figure(smoothing.before_after_figure(s, d["windows"][window], results, mean, mode),
                                     f"fig{number}_{s}", f"Fig. {number}: mean filter, Bezier and NACOA on {s} "
                                     f"window {window} (category {category}), curvature reduction in each title"))
        parts.append(self.figure(smoothing.tradeoff_figure({s: d["rows"] for s, d in data.items()}),
                                 "fig14_reduction_vs_deviation",
                                 "Ours: curvature reduction against the two-sided deviation from the original path, "
                                 "per method (mean: large marker), the trade-off the paper does not report"))
        return "\n".join(parts)

    # ---- sequencing (Xie & Zhu) -------------------------------------------------------------
    def sequencing(self) -> str:
        seq = self.cfg.sequence
        metrics_path, timing_path = self.layout.sequence_metrics, self.layout.sequence_timing
        sheet_path = self.layout.sheet(seq.figure_sheet)
        plans_path = self.layout.sheet_plans(seq.figure_sheet)
        require([metrics_path, timing_path, sheet_path, plans_path], "sequence")
        metrics, plans = read_json(metrics_path), read_json(plans_path)
        parts = [self.table(sequencing.sequencing_table(metrics, read_json(timing_path)), "table7_sequencing"),
                 self.table(sequencing.baselines_table(metrics), "table8_sequencing_baselines"),
                 self.table(sequencing.expansion_table(metrics, seq.expansion_study.sheet), "table9_expansion")]
        shown = {title: plans[m] for title, m in (("without collision avoidance", "s_shaped_no_avoidance"),
                                                  ("with collision avoidance", "s_shaped")) if m in plans}
        if shown:
            parts.append(self.figure(sequencing.sheet_figure(read_json(sheet_path), shown), "fig15_sequence",
                                     f"Xie & Zhu, Fig. 10's style: the S-shaped plan of the {seq.figure_sheet}-part "
                                     "sheet, entry points red, exit points yellow, transitions blue, collisions red"))
        return "\n".join(parts)

    # ---- corner smoothing and feedrate (the NURBS corner paper) --------------------------------------------
    def corners_and_feedrate(self) -> str:
        lay = self.layout
        corner, timing, profiles, curves = lay.corner_metrics, lay.corner_timing, lay.corner_profiles, lay.corner_curves
        require([lay.corner_rows, corner, timing, profiles, curves], "corner")
        windows = {s: lay.feedrate_summary(s) for s in self.shapes}
        require(list(windows.values()), "feedrate")
        metrics, per_shape = read_json(corner), {s: read_json(p) for s, p in windows.items()}
        cases, methods = list(metrics["cases"]), list(self.cfg.corner.methods)
        arrays = load_arrays(profiles, [], "corner profiles", "corner")
        rows = read_csv(lay.corner_rows)
        parts = [self.table(corner_report.cases_table(metrics, rows, self.cfg.corner.delta_max,
                                                          self.cfg.feedrate.band),
                            "table10_corner_cases"),
                 self.table([corner_report.corners_table(rows, case, methods) for case in cases], "table13_corners"),
                 self.table(corner_report.surrogate_table(metrics, read_json(timing)), "table11_surrogates"),
                 self.table(corner_report.pso_study_table(metrics), "table14_pso_size"),
                 self.table([corner_report.windows_table(per_shape, mode) for mode in self.cfg.optimize.modes],
                            "table12_time_saved"),
                 self.figure(corner_report.profiles_figure(arrays, cases, methods), "fig16_corner_profiles",
                             "NURBS corner paper, Figs. 11-14: each case path smoothed by every method (top) and "
                             "its planned feed (bottom)"),
                 self.figure(corner_report.training_figure(read_columns(curves)), "fig17_surrogate_training",
                             "NURBS corner paper, Figs. 8-9: training loss of FDLS and SDLS")]
        return "\n".join(parts)

    def sections(self) -> list[Section]:
        plan: list[tuple[str, Callable[[], str]]] = [
            ("Table 1: roughness categories", self.categories),
            ("Table 2: hyperparameters and training time", self.hyperparameters),
            ("Table 3: classification metrics", self.performance),
            ("Figures 6-7: training curves", self.curves),
            ("Ours: confusion matrices", self.confusion),
            ("Ours: generalisation across shapes and to real G-code", self.cross_shape),
            ("Table 4: inference time, FP32 and INT8", self.inference),
            ("Table 5: classification of random windows", self.classification),
            ("Table 6: optimisers and curvature reduction", self.optimisers),
            ("Figures 8-11 and the reduction / deviation trade-off", self.smoothing_figures),
            ("Xie & Zhu: sequencing many parts on one sheet", self.sequencing),
            ("NURBS corner paper: corner smoothing, feedrate and machining time", self.corners_and_feedrate),
        ]
        result = []
        for title, build in plan:
            try:
                result.append(Section(title, build()))
            except Missing as missing:
                result.append(Section(title, missing=[str(p) for p in missing.paths], stage=missing.stage))
            except (KeyError, TypeError, IndexError, ValueError) as exc:  # a file of the right kind, wrong content
                raise SystemExit(f"report section {title!r}: an input of `dvc repro {_required_by[0]}` is malformed "
                                 f"({type(exc).__name__}: {exc})") from None
        return result

