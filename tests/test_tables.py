"""Report tables: rendering and Table 3 beside the paper."""

import pytest

from toolpath.reports.tables import Table, table3


def test_markdown_and_latex_render_the_same_cells():
    table = Table("T_1 & more", ["a", "b %"])
    table.add(["x_y", "**1.00**"])
    md, tex = table.markdown(), table.latex()
    assert "| x_y | **1.00** |" in md and "\n|---|---|\n" in md
    assert r"x\_y & \textbf{1.00} \\" in tex and r"\caption{T\_1 \& more}" in tex and r"b \%" in tex
    with pytest.raises(ValueError, match="2 columns"):
        table.add(["only one"])


def test_table3_puts_the_paper_beside_ours_and_marks_the_best():
    def metrics(acc, loss):
        return {"accuracy": acc, "loss": loss, "precision": acc, "recall": acc, "f1": acc, "auc": acc}

    table = table3("gear", {"mcrl": metrics(0.9, 0.2), "rule": metrics(1.0, 0.1)})
    mcrl, rule = table.rows
    assert mcrl[1] == "90.00 / 94.75 (-4.75)"  # worse than the paper: shown negative
    assert mcrl[2] == "20.00 / 14.26 (+5.74)"  # a higher loss than the paper's
    assert rule[1] == "**100.00** / -" and rule[2] == "**10.00** / -"  # best per column, no paper row
