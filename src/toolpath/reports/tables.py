"""Tables as data, rendered to Markdown and LaTeX with the paper's value beside ours.

A :class:`Table` holds a title, column headers and rows of cells; numbers are formatted once,
so the Markdown and LaTeX versions always agree.  :func:`table3` builds Table 3 (ours beside the
paper, the difference, the best of each of our columns in bold).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from toolpath.reports.paper import LOWER_IS_BETTER, TABLE3, TABLE3_COLUMNS

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


def _ours(metrics: Mapping, column: str) -> float:
    """Our figure in the paper's units: per cent, and the loss x 100 as the paper prints it."""
    return 100.0 * float(metrics[column])


def table3(shape: str, test_metrics: Mapping[str, Mapping]) -> Table:
    """Table 3 for one shape: per model, ours / paper / difference for each column; the best of ours
    per column in bold (lowest loss, highest otherwise).  Models without a paper row (the exact rule)
    show a dash there."""
    headers = ["model", *(f"{c} ours / paper (diff)" for c in TABLE3_COLUMNS)]
    table = Table(f"Table 3, {shape}: test metrics, ours beside the paper (per cent; loss x 100)", headers)
    best = {}
    for column in TABLE3_COLUMNS:
        values = [_ours(m, column) for m in test_metrics.values()]
        best[column] = min(values) if column in LOWER_IS_BETTER else max(values)
    for model, metrics in test_metrics.items():
        cells: list[object] = [model]
        paper = TABLE3.get(shape, {}).get(model)
        for k, column in enumerate(TABLE3_COLUMNS):
            ours = _ours(metrics, column)
            text = f"{ours:.2f}"
            if abs(ours - best[column]) < 1e-9:
                text = f"**{text}**"
            cells.append(f"{text} / {paper[k]:.2f} ({ours - paper[k]:+.2f})" if paper else f"{text} / -")
        table.add(cells)
    table.notes.append("Bold: our best per column. A negative difference in accuracy, precision, recall, F1 or "
                       "AUC (positive in loss) means ours is worse than the paper's.")
    return table
