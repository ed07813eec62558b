"""The README's generated block: the headline figure and one-line-per-shape summaries of Table 3
and Table 6, built from the same metrics as the report (no hand-typed numbers)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from toolpath.models.training.metrics import DEGENERATE
from toolpath.reports.paper import PAPER_REDUCTION, TABLE3

HEADLINE = "fig8_methods"


def table3_summary(metrics: Mapping[str, Mapping[str, Mapping]]) -> str:
    """Per shape: MCRL's test accuracy / macro F1 (mean +- sd over the training seeds) on the paper's
    input (``mcrl_xy``, Table 3a) and on ours (``mcrl``, Table 3b) beside the paper's, the best learned
    model (:func:`~toolpath.models.training.replicates.best_learned`: chosen by validation F1, its test figures
    shown), the rule."""
    from toolpath.models.training.replicates import best_learned

    lines = ["| shape | MCRL on the paper's input (coordinates), accuracy / F1, mean +- sd over seeds (paper) | "
             "MCRL on our turning terms | best learned model (chosen by validation F1), test accuracy / F1 | "
             "exact rule accuracy |", "|---|---|---|---|---|"]
    for shape, models in metrics.items():
        learned = {m: v["replicates"] for m, v in models.items() if m != "rule"}
        if not learned:
            continue
        scored = {m: v for m, v in learned.items() if v["degenerate"] < v["replicates"]}
        best = best_learned(learned)
        paper = TABLE3.get(shape, {}).get("mcrl")
        paper_cell = f" ({paper[0]:.1f} % / {paper[4]:.1f} %)" if paper else ""
        best_cell = (f"{best} {_spread(scored[best]['test']['accuracy'])} / {_spread(scored[best]['test']['f1'])}"
                     if best else "-")
        rule = models.get("rule", {}).get("test", {}).get("accuracy")
        lines.append(f"| {shape} | {_mcrl_cell(learned.get('mcrl_xy'), paper_cell)} | "
                     f"{_mcrl_cell(learned.get('mcrl'), '')} | {best_cell} | "
                     f"{f'{100 * rule:.1f} %' if rule is not None else '-'} |")
    return "\n".join(lines) + "\n"


def _mcrl_cell(summary: Mapping | None, paper_cell: str) -> str:
    from toolpath.models.training.replicates import describe

    if summary is None:
        return "-"
    if summary["degenerate"] == summary["replicates"]:
        return DEGENERATE + paper_cell
    note = describe(summary)
    return (f"{_spread(summary['test']['accuracy'])} / {_spread(summary['test']['f1'])}" + paper_cell
            + (f", {note}" if note else ""))


def paired_summary(paired: Mapping[str, Mapping[str, Mapping[str, Mapping]]]) -> str:
    """One sentence per shape and MCRL, each claim the verdict of its paired accuracy interval (Table 3c):
    better than / no difference shown against / worse than."""
    wording = {"better": "better than", "no difference shown": "no difference shown against",
               "worse": "worse than"}
    lines = []
    for shape, anchors in paired.items():
        for anchor, rivals in anchors.items():
            groups: dict[str, list[str]] = {}
            for rival, result in rivals.items():
                if "accuracy" in result:
                    groups.setdefault(result["accuracy"]["verdict"], []).append(rival)
            said = [f"{wording[v]} {', '.join(groups[v])}" for v in wording if groups.get(v)]
            if said:
                lines.append(f"- {shape}, {anchor}: test accuracy {'; '.join(said)} (95 % paired interval over "
                             "test programs and seeds, Table 3c).")
    return "\n".join(lines) + ("\n" if lines else "")


def _spread(figure: Mapping) -> str:
    """A mean +- sd figure in per cent."""
    sd = figure.get("sd")
    return f"{100 * figure['mean']:.1f}" + (f" +- {100 * sd:.1f}" if sd is not None else "") + " %"


def table6_summary(metrics: Mapping[str, Mapping]) -> str:
    """Per shape and mode: Sec. 5.2.4's reduction on categories 2-4 (the windows Sec. 5.3 smooths) of mean
    filter, Bezier and NACOA with 95 % intervals beside the paper's 54 / 67 / 78 %, and the dispatch."""
    from toolpath.reports.smoothing_tables import MODE_LABEL, against_paper, with_interval

    lines = ["| shape | mode | mean filter | Bezier | NACOA | Sec. 5.3 dispatch |", "|---|---|---|---|---|---|"]
    for shape, m in metrics.items():
        for mode in ("none", "tube"):
            node = m.get("paper_metric", {}).get(mode)
            if not node or not all(node["methods"].get(k, {}).get("categories_2_4") for k in PAPER_REDUCTION):
                continue
            cells = [f"{with_interval(node['methods'][k]['categories_2_4'])} % "
                     f"({against_paper(node['methods'][k]['categories_2_4'], PAPER_REDUCTION[k])})"
                     for k in PAPER_REDUCTION]
            cells.append(f"{with_interval(node['dispatch'])} %" if "dispatch" in node else "-")
            lines.append(f"| {shape} | {MODE_LABEL[mode]} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def readme_block(summaries: Mapping[str, str], profile: str, commit: str, out: Path) -> str:
    """The README block: provenance, the headline figure, the summaries, how to regenerate."""
    parts = [f"From profile `{profile}` at commit `{commit}`; the whole report with every table and figure is "
             f"[`{out}/report.md`]({out}/report.md). Regenerate with `make repro`.", "",
             f"![Every smoothing method on one drawn window per shape]({out}/figures/{HEADLINE}.png)", ""]
    if "table3" in summaries:
        parts += ["**Table 3 in brief** (test programs; the paper's figure in brackets):", "", summaries["table3"]]
    if summaries.get("paired"):
        parts += ["**Paired comparisons** (a claim only where its interval excludes 0):", "", summaries["paired"]]
    if "table6" in summaries:
        parts += ["**Sec. 5.2.4 in brief** (mean LocalCurvature reduction over the sampled test windows of "
                  "categories 2-4, the ones Sec. 5.3 smooths, with 95 % bootstrap intervals over windows):",
                  "", summaries["table6"]]
    return "\n".join(parts)
