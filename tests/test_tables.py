"""Report tables: rendering (Table 3 beside the paper: tests/test_replicates.py)."""

import pytest

from toolpath.reports.tables import Table


def test_markdown_and_latex_render_the_same_cells():
    table = Table("T_1 & more", ["a", "b %"])
    table.add(["x_y", "**1.00**"])
    md, tex = table.markdown(), table.latex()
    assert "| x_y | **1.00** |" in md and "\n|---|---|\n" in md
    assert r"x\_y & \textbf{1.00} \\" in tex and r"\caption{T\_1 \& more}" in tex and r"b \%" in tex
    with pytest.raises(ValueError, match="2 columns"):
        table.add(["only one"])


