"""Tables as data, rendered to Markdown and LaTeX with the paper's value beside ours.

A :class:`Table` holds a title, column headers and rows of cells; numbers are formatted once,
so the Markdown and LaTeX versions always agree.  :func:`categories_table` (Table 1's category counts), :func:`table2`
(hyperparameters and training time) and :func:`table3` (ours beside the paper, the difference,
the best of each of our columns in bold) cover the classification side.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from toolpath.models.training.metrics import DEGENERATE
from toolpath.reports.paper import LOWER_IS_BETTER, TABLE2, TABLE3, TABLE3_COLUMNS

CATEGORY_NAMES = {1: "smooth", 2: "slightly rough", 3: "rugged", 4: "sharp turning corner"}


def category_bounds(bounds: tuple[float, float, float]) -> dict[int, str]:
    """The LocalCurvature range of each category for thresholds ``bounds`` (``label.bounds``)."""
    low, mid, high = bounds
    return {1: f"<= {low:g}", 2: f"{low:g} - {mid:g}", 3: f"{mid:g} - {high:g}", 4: f">= {high:g}"}

LATEX_SPECIAL = {"&": r"\&", "%": r"\%", "_": r"\_", "#": r"\#", "$": r"\$", "{": r"\{", "}": r"\}"}


@dataclass
class Table:
    title: str
    headers: Sequence[str]
    rows: list[list[str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def add(self, cells: Sequence[object]) -> None:
        if len(cells) != len(self.headers):
            raise ValueError(f"row of {len(cells)} cells for {len(self.headers)} columns in {self.title!r}")
        self.rows.append([str(c) for c in cells])

    def markdown(self) -> str:
        lines = [f"**{self.title}**", "", "| " + " | ".join(self.headers) + " |",
                 "|" + "|".join("---" for _ in self.headers) + "|"]
        lines += ["| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |" for row in self.rows]
        lines += ["", *(f"{n}" for n in self.notes)] if self.notes else []
        return "\n".join(lines) + "\n"

    def latex(self) -> str:
        def esc(text: str) -> str:
            bold = text.startswith("**") and text.endswith("**") and len(text) > 4
            body = "".join(LATEX_SPECIAL.get(ch, ch) for ch in (text[2:-2] if bold else text))
            return rf"\textbf{{{body}}}" if bold else body

        spec = "l" + "r" * (len(self.headers) - 1)
        lines = [r"\begin{table}[ht]", r"\centering", rf"\caption{{{esc(self.title)}}}",
                 rf"\begin{{tabular}}{{{spec}}}", r"\hline",
                 " & ".join(esc(h) for h in self.headers) + r" \\", r"\hline"]
        lines += [" & ".join(esc(c) for c in row) + r" \\" for row in self.rows]
        lines += [r"\hline", r"\end{tabular}", r"\end{table}"]
        return "\n".join(lines) + "\n"


def _ours(figures: Mapping, column: str) -> tuple[float, float | None]:
    """Our mean and sd over the replicates in the paper's units: per cent, the loss x 100 as the paper
    prints it."""
    entry = figures[column]
    sd = entry.get("sd")
    return 100.0 * float(entry["mean"]), (None if sd is None else 100.0 * float(sd))


INPUT_BLOCKS = {"coordinates": "the paper's input: the window's coordinates (Sec. 5.1.1), each model's first layers "
                               "a learned difference stem",
                "turning": "our input: per-point turning terms (1 - cos, sin) of Eq. 1-3"}
LOGISTIC = "logistic regression (reference)"  # Table 3's row for models.linear, beside the exact rule
PROTOCOL_SUFFIX = "_xy"  # a model of the coordinates block is named after its paper row plus this


def paper_row(model: str) -> str:
    """The paper's Table 3 row a model stands for (``mcrl_xy``: ``mcrl``)."""
    return model.removesuffix(PROTOCOL_SUFFIX)


def table3(shape: str, summaries: Mapping[str, Mapping], block: str = "turning",
           protocol_note: str | None = None) -> Table:
    """Table 3 for one shape: per model, our mean +- sd over the training seeds / the paper / the
    difference of the mean, for each column; the best of our means per column in bold (lowest loss,
    highest otherwise).  ``summaries``: per model the ``replicates`` entry of its train metrics
    (:func:`toolpath.models.training.replicates.summarise`).  A model all of whose seeds predict one class is
    shown as degenerate, never scored; one some of whose seeds do is scored on the others and says so.
    Models without a paper row (the exact rule) show a dash there."""
    from toolpath.models.training.replicates import describe

    headers = ["model", *(f"{c} ours / paper (diff)" for c in TABLE3_COLUMNS),
               "accuracy, 95 % interval (programs)", "seeds"]
    letter = "a" if block == "coordinates" else "b"
    table = Table(f"Table 3{letter}, {shape}, {INPUT_BLOCKS[block]}: test metrics, mean +- sd over training seeds, "
                  "ours beside the paper (per cent; loss x 100)", headers)
    scored = {m: v for m, v in summaries.items() if v["degenerate"] < v["replicates"]}
    best = {}
    for column in TABLE3_COLUMNS:  # the best learned model: the exact rule is the reference, not a rival
        values = [_ours(v["test"], column)[0] for m, v in scored.items() if m not in ("rule", LOGISTIC)]
        best[column] = (min(values) if column in LOWER_IS_BETTER else max(values)) if values else None
    for model, summary in summaries.items():
        note = describe(summary)
        if model not in scored:
            table.add([model, *([DEGENERATE] * len(TABLE3_COLUMNS)), "-", str(summary["replicates"])])
            continue
        cells: list[object] = [f"{model} ({note})" if note else model]
        paper = TABLE3.get(shape, {}).get(paper_row(model))
        for k, column in enumerate(TABLE3_COLUMNS):
            mean, sd = _ours(summary["test"], column)
            text = f"{mean:.2f}" + (f" +- {sd:.2f}" if sd is not None else "")
            if best[column] is not None and abs(mean - best[column]) < 1e-9:
                text = f"**{text}**"
            cells.append(f"{text} / {paper[k]:.2f} ({mean - paper[k]:+.2f})" if paper else f"{text} / -")
        ci = summary.get("accuracy_ci")
        cells.append(f"{100 * ci['low']:.1f} - {100 * ci['high']:.1f} ({ci['programs']})" if ci else "-")
        cells.append(str(summary["replicates"]))
        table.add(cells)
    table.notes.append(
        "Ours: mean +- standard deviation over the training seeds (column *seeds*; the exact rule learns nothing "
        "and runs once). Bold: the best mean of a network per column; the logistic regression (one deterministic fit "
        "on the flattened input) shows what the input alone gives. A negative difference in accuracy, "
        "precision, recall, F1 or AUC (positive in loss) means ours is worse than the paper's. A model whose "
        f"every test prediction falls into one class is shown as *{DEGENERATE}*, not scored. The interval is a "
        "percentile bootstrap over test programs (the independent unit, not windows) of the accuracy averaged "
        "over the seeds.")
    if protocol_note:
        table.notes.append(protocol_note)
    return table


def corpus_table(by_origin: Mapping[str, Mapping]) -> Table:
    """Real G-code windows by origin (all, mostly from linearised arcs, the rest): counts, rough
    windows, accuracy against the rule's labels, and each category's count and recall."""
    names = {"all": "all windows", "arcs": "from G2/G3 arcs (> half the points)", "lines": "from G1 lines"}
    headers = ["windows", "count", "rough (cat. >= 2)", "accuracy %", "macro F1 %", "majority class %",
               *(f"cat. {c} count (recall %)" for c in CATEGORY_NAMES)]
    table = Table("Table 15 (ours): the all-shapes MCRL on real G-code, by where the windows come from", headers)
    for key, name in names.items():
        entry = by_origin.get(key, {"windows": 0})
        if not entry["windows"]:
            table.add([name, "0", *(["-"] * (len(headers) - 2))])
            continue
        classes = [entry["per_class"][str(c)] for c in CATEGORY_NAMES]
        table.add([name, entry["windows"], entry["rough_windows"], f"{100 * entry['accuracy']:.1f}",
                   f"{100 * entry['f1']:.1f}", f"{100 * entry['majority_accuracy']:.1f}",
                   *(f"{c['count']} ({100 * c['recall']:.0f})" if c["recall"] is not None else "0 (-)"
                     for c in classes)])
    table.notes.append("Labels: the exact LocalCurvature rule (Eq. 3) on each window. The reader linearises arcs into "
                       "chords within its chord tolerance, so an arc window's turns are the reader's, not CAM "
                       "roughness. Recall is left blank for a category with no window.")
    return table


def categories_table(label_metrics: Mapping[str, Mapping], bounds: tuple[float, float, float]) -> Table:
    """Table 1's categories (thresholds ``bounds``) with our window count and share per shape (the paper
    gives none)."""
    shapes = list(label_metrics)
    table = Table("Table 1: roughness categories (LocalCurvature, Eq. 3) with our window counts and shares",
                  ["category", "LocalCurvature", *(f"{s} windows (share)" for s in shapes)])
    for category, name in CATEGORY_NAMES.items():
        cells = [f"{category} {name}", category_bounds(bounds)[category]]
        for shape in shapes:
            m = label_metrics[shape]
            cells.append(f"{m['class_count'][str(category)]} ({100 * m['class_share'][str(category)]:.1f} %)")
        table.add(cells)
    table.add(["all", "", *(f"{label_metrics[s]['windows']} (100 %)" for s in shapes)])
    table.notes.append("The paper gives the bounds only (1.9, 3.5, 7.6; ours are `label.bounds`). Our windows: "
                       "every window of every program.")
    return table


def table2(profile: str, ours: Mapping[str, Mapping[str, Mapping]], runs: Mapping[str, Mapping]) -> Table:
    """Table 2: the paper's hyperparameters beside the settings each MCRL of the report profile trained
    with, and the measured training time.  ``ours``: per shape, per MCRL model (one per input), the
    settings :func:`toolpath.pipeline.settings.training` gives the train stage (the composed config, not
    a copy of it); ``runs``: per shape ``all_seconds`` (every learned model, every seed) and per model
    ``seconds`` (its seeds) and ``epochs_run``."""
    headers = ["shape", "source", "learning rate", "decay rate", "decay steps", "batch size", "epochs",
               "MCRL training time (all seeds)", "all learned models"]
    table = Table("Table 2: hyperparameters per shape, the paper's beside ours, with the training time", headers)
    notes: set[str] = set()
    for shape, paper in TABLE2.items():
        if shape not in ours:
            continue
        lr, rate, steps, batch, epochs, minutes = paper
        table.add([shape, "paper (Table 2)", f"{lr:g}", f"{rate:g}", steps, batch, epochs, f"{minutes} min (GPU)", "-"])
        run = runs.get(shape, {})
        for k, (model, o) in enumerate(ours[shape].items()):
            own = run.get(model, {})
            staircase = o.get("schedule", "step") == "step"
            decay = [f"{o['decay_rate']:g}", str(o["decay_steps"])] if staircase else [f"- ({o['schedule']})"] * 2
            stopped = o.get("patience") is not None and "epochs_run" in own
            epochs = f"{own['epochs_run']} of {o['epochs']}" if stopped else str(o["epochs"])
            notes.add("early stopping on validation loss" if o.get("patience") is not None else
                      "no early stopping: every epoch runs" + ("; the weights of the epoch with the lowest "
                                                               "validation loss are restored"
                                                               if o.get("restore_best") else ""))
            seconds = f"{own['seconds'] / 60:.1f} min" if "seconds" in own else "-"
            every = f"{run['all_seconds'] / 60:.1f} min" if k == 0 and "all_seconds" in run else "-"
            table.add([shape, f"profile `{profile}`: {model}", f"{o['lr']:g}", *decay, o["batch_size"], epochs,
                       seconds, every])
    table.notes.append(f"Ours: the settings each MCRL trained with (`{profile}` profile, composed from conf/); "
                       f"{'; '.join(sorted(notes))}. Times are measured wall-clock on this machine's CPU "
                       "threads; the paper's are minutes on an RTX 4070 for the epochs it ran. The `paper` profile "
                       "(`+experiment=paper`) runs Table 2 as printed (tests/test_config.py checks it).")
    return table


def paired_table(shape: str, paired: Mapping[str, Mapping[str, Mapping]]) -> Table:
    """Table 3c for one shape: MCRL (on each input) minus every other model, accuracy and macro F1 in
    points with their 95 % paired bootstrap interval over test programs and seeds, and the verdict
    the interval allows (:func:`toolpath.models.training.metrics.paired_bootstrap`)."""
    headers = ["MCRL", "against", "accuracy difference (interval)", "macro F1 difference (interval)",
               "verdict (accuracy / F1)"]
    table = Table(f"Table 3c, {shape}: MCRL minus each model on the same test programs (points), 95 % interval "
                  "resampling programs and seeds together", headers)
    for anchor, rivals in paired.items():
        for rival, result in rivals.items():
            if "accuracy" not in result:
                table.add([anchor, rival, "-", "-", result["verdict"]])
                continue
            cells = [f"{100 * r['difference']:+.2f} ({100 * r['low']:+.2f} to {100 * r['high']:+.2f})"
                     for r in (result["accuracy"], result["f1"])]
            table.add([anchor, rival, *cells, f"{result['accuracy']['verdict']} / {result['f1']['verdict']}"])
    table.notes.append("Better / worse: the 95 % interval lies above / below 0; otherwise no difference is shown. "
                       "Each bootstrap draw takes the test programs with replacement (the same for both models) and "
                       "each model's training seeds with replacement; seeds whose predictions fell into one class "
                       "are left out.")
    return table
