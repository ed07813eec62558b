"""The tube-limit benchmark's figures, on rows built by hand (the runs themselves are a benchmark)."""

import pytest

from toolpath.bench.tube_limit import by_window, limit_figures


def test_the_oracle_dispatch_takes_each_windows_best_and_the_stage_dispatch_its_own_method():
    rows = [{"window": w, "category": c, "method": m, "encoding": "plain", "reduction_pct": r}
            for w, c, m, r in ((1, 2, "mean_filter", 40.0), (1, 2, "bezier", 50.0), (1, 2, "nacoa", 60.0),
                               (2, 4, "mean_filter", 90.0), (2, 4, "bezier", 95.0), (2, 4, "nacoa", 97.0))]
    rows.append({"window": 2, "category": 4, "method": "pso", "encoding": "shifted", "reduction_pct": 99.0})
    best, category = by_window(rows)
    assert category == {1: 2, 2: 4} and best[2]["pso@shifted"] == 99.0
    figures = limit_figures(best, category, {1: 70.0, 2: 96.0}, {2: "mean_filter", 3: "bezier", "4": "nacoa"})
    assert figures["2"] == {"windows": 1, "stage_nacoa_pct": 60.0, "stronger_nacoa_pct": 70.0,
                            "stage_dispatch_pct": 40.0, "oracle_dispatch_pct": 70.0}
    assert figures["4"]["oracle_dispatch_pct"] == 99.0 and figures["4"]["stage_dispatch_pct"] == 97.0
    pooled = figures["2-4"]
    assert pooled["windows"] == 2 and pooled["stage_dispatch_pct"] == pytest.approx(68.5)
    assert pooled["oracle_dispatch_pct"] == pytest.approx(84.5) and figures["3"] == {"windows": 0}
