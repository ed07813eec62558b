"""Sec. 5.2.4's metric on categories 2-4 with bootstrap intervals (toolpath.smoothing.paper_metric),
on rows built by hand, and the report's sentences that follow the intervals."""

import pytest

from toolpath.reports import smoothing_tables
from toolpath.smoothing.paper_metric import paired_differences, paper_metric


def row(window, category, method, reduction, before=2.0, mode="tube", encoding="plain", **extra):
    return {"window": window, "category": category, "method": method, "mode": mode, "encoding": encoding,
            "reduction_pct": reduction, "local_curvature_before": before,
            "local_curvature_after": before * (1 - reduction / 100), **extra}


def sample_rows():
    rows = []
    for w in range(12):
        category = 1 + w % 4
        # NACOA 90 on every window, Bezier 60, mean filter 30 (+-1 by window): one order, always
        rows += [row(w, category, "nacoa", 90 + (w % 3 - 1)), row(w, category, "bezier", 60 + (w % 3 - 1)),
                 row(w, category, "mean_filter", 30 + (w % 3 - 1))]
    return rows


def test_the_pooled_figure_leaves_category_1_out_and_brackets_its_mean():
    result = paper_metric(sample_rows(), {2: "mean_filter", 3: "bezier", 4: "nacoa"}, seed=0)["tube"]
    nacoa = result["methods"]["nacoa"]
    pooled = nacoa["categories_2_4"]
    assert pooled["windows"] == 9 and nacoa["category_1"]["windows"] == 3
    # windows 1, 2, 3, 5, 6, 7, 9, 10, 11 (category 2-4): w % 3 - 1 sums to 0 over them, so the mean is 90
    assert pooled["mean_reduction_pct"] == pytest.approx(90.0)
    low, high = pooled["mean_reduction_ci"]
    assert low <= 90.0 <= high and high - low < 2.0
    # every window has LocalCurvature 2 before, so the summed reduction equals the mean one
    assert pooled["summed_reduction_pct"] == pytest.approx(90.0)
    assert set(nacoa["per_category"]) == {"2", "3", "4"}


def test_the_dispatch_row_takes_each_categorys_method():
    result = paper_metric(sample_rows(), {2: "mean_filter", 3: "bezier", 4: "nacoa"}, seed=0)["tube"]
    # categories 2 / 3 / 4 are windows 1, 5, 9 / 2, 6, 10 / 3, 7, 11: offsets (0, 0, 0) / (1, -1, 0) / (-1, 0, 1)
    assert result["dispatch"]["mean_reduction_pct"] == pytest.approx((30 * 3 + 60 * 3 + 90 * 3) / 9)
    assert result["dispatch"]["windows"] == 9


def test_a_ranking_that_holds_on_every_window_holds_in_every_resample():
    ranking = paper_metric(sample_rows(), {2: "mean_filter", 3: "bezier", 4: "nacoa"}, seed=0)["tube"]["ranking"]
    assert ranking["order"] == ["nacoa", "bezier", "mean_filter"] and ranking["probability"] == 1.0


def test_a_close_ranking_is_not_called_a_difference():
    rows = []
    for w in range(20):
        noise = 15.0 if w % 2 else -15.0
        rows += [row(w, 2 + w % 3, "nacoa", 70 + noise), row(w, 2 + w % 3, "bezier", 69 - noise),
                 row(w, 2 + w % 3, "mean_filter", 80)]
    metrics = {"gear": {"paper_metric": paper_metric(rows, {2: "mean_filter", 3: "bezier", 4: "nacoa"}, seed=1)}}
    note = smoothing_tables.ranking_notes(metrics)[0]
    assert "not shown to differ" in note or "differs" in note
    # NACOA vs Bezier flips from resample to resample: our order holds in well under every resample
    assert metrics["gear"]["paper_metric"]["tube"]["ranking"]["probability"] < 0.95


def test_against_the_paper_says_above_or_below_only_outside_the_interval():
    figure = {"mean_reduction_pct": 75.0, "mean_reduction_ci": [70.0, 80.0]}
    assert smoothing_tables.against_paper(figure, 78.0).startswith("no difference")
    assert smoothing_tables.against_paper(figure, 85.0).startswith("below")
    assert smoothing_tables.against_paper(figure, 54.0).startswith("above")


def test_paired_differences_pair_windows_and_bracket_the_mean():
    rows = [row(w, 4, "nacoa_matched", 80 + w) for w in range(8)] + [row(w, 4, "pso", 70 + w) for w in range(8)]
    rows += [row(w, 4, "pso", 10.0, encoding="shifted") for w in range(8)]
    diffs = paired_differences(rows, "nacoa_matched", seed=2)["tube"]
    assert diffs["pso"]["mean_difference_pct"] == pytest.approx(10.0)
    assert diffs["pso"]["ci"] == pytest.approx([10.0, 10.0])  # the same 10 points on every window
    assert diffs["pso@shifted"]["mean_difference_pct"] == pytest.approx(73.5)


def test_one_window_has_no_interval_and_the_report_says_so():
    rows = [row(0, 4, "nacoa", 80.0), row(0, 4, "bezier", 50.0), row(0, 4, "mean_filter", 40.0)]
    pooled = paper_metric(rows, {4: "nacoa"}, seed=0)["tube"]["methods"]["nacoa"]["categories_2_4"]
    assert all(v != v for v in pooled["mean_reduction_ci"])  # NaN, written as null in the JSON
    written = {**pooled, "mean_reduction_ci": [None, None]}
    assert smoothing_tables.with_interval(written) == "80.0 [no interval]"
    assert smoothing_tables.against_paper(written, 78.0) == "too few windows for an interval"


def test_the_study_table_says_when_the_largest_count_was_chosen():
    study = {"generations": [20, 40, 80], "mean_fitness": [2.0, 1.5, 1.2], "best_mean_fitness": 1.2,
             "within_pct": 1.0, "chosen": 80, "windows": 6}
    table = smoothing_tables.study_table({"gear": {"convergence_study": study}})
    assert table.rows == [["gear", "6", "2.0000", "1.5000", "1.2000", "G = 80"]]
    assert any("still falling" in n for n in table.notes)
    study = {**study, "mean_fitness": [1.21, 1.2, 1.2], "chosen": 20}
    notes = smoothing_tables.study_table({"gear": {"convergence_study": study}}).notes
    assert not any("still falling" in n for n in notes)


def test_choose_generations_takes_the_cheapest_within_the_share():
    import numpy as np

    from toolpath.smoothing.runs import choose_generations

    chosen = choose_generations([10, 20, 40], np.array([[2.0, 2.2], [1.02, 1.0], [1.0, 1.0]]), 1.0)
    assert chosen["chosen"] == 20 and chosen["best_mean_fitness"] == 1.0  # 1.01 is within 1 % of 1.0
    assert choose_generations([10, 20], np.array([[1.5], [1.0]]), 1.0)["chosen"] == 20


def test_a_mode_capped_per_category_runs_on_the_first_windows_of_each_draw():
    from toolpath.smoothing.runs import plan

    chosen = [(10, 2, False), (11, 2, False), (12, 2, False), (20, 3, False), (21, 3, False)]
    ocfg = {"methods": ["mean_filter"], "modes": ["none", "tube"], "encodings": ["plain"],
            "sample": {"per_category_by_mode": {"none": 2}}}
    runs = {(t["mode"], t["window"]) for t in plan(chosen, ocfg)}
    assert {w for m, w in runs if m == "none"} == {10, 11, 20, 21}
    assert {w for m, w in runs if m == "tube"} == {10, 11, 12, 20, 21}
    with pytest.raises(ValueError, match="per_category_by_mode"):
        plan(chosen, {**ocfg, "sample": {"per_category_by_mode": {"bound": 2}}})


class _Serial:
    """The one method of an executor :func:`study_smoothers` uses, in this process."""

    @staticmethod
    def map(function, cells, chunksize=1):
        return map(function, cells)


def test_the_smoothers_settings_are_the_lowest_mean_fitness_per_mode():
    import numpy as np

    from toolpath.smoothing.methods import smooth
    from toolpath.smoothing.runs import settings_by_mode, smoother_grid, study_smoothers

    t = np.linspace(0.0, 1.0, 30)
    zigzag = np.column_stack([10.0 * t, 0.04 * (-1.0) ** np.arange(30)])  # noise 0.08 mm peak to peak
    zigzag[0, 1] = zigzag[-1, 1] = 0.0
    grid = {"windows_per_category": 1, "mean_filter": {"width": [3, 5], "passes": [1, 4]}, "bezier": {"degree": [2, 5]}}
    ocfg = {"modes": ["none", "tube"], "smoother_study": grid, "tolerance": 0.05, "penalty_weight": 10.0,
            "mean_filter": {"width": 5, "passes": 3}, "bezier": {"degree": 5}}
    study = study_smoothers(_Serial(), [zigzag], ocfg)
    assert study["windows"] == 1 and set(study["modes"]) == {"none", "tube"}
    by_mode = settings_by_mode(ocfg, study)
    for mode, node in study["modes"].items():
        for method in ("mean_filter", "bezier"):
            fitness = node[method]["mean_fitness"]
            best = node[method]["settings"][int(np.argmin(fitness))]
            assert node[method]["chosen"] == best == by_mode[mode][method]
            # the study's figure is what the stage's run with that setting reaches
            assert smooth(zigzag, method, by_mode[mode], mode, 0, check=False).objective == min(fitness)
    # unbounded, the heaviest filter flattens the zigzag most; its figures differ, so the choice is real
    assert study["modes"]["none"]["mean_filter"]["chosen"] == {"width": 5, "passes": 4}
    assert len(set(study["modes"]["none"]["mean_filter"]["mean_fitness"])) == 4
    assert [m for m, _ in smoother_grid(grid)] == ["mean_filter"] * 4 + ["bezier"] * 2
    with pytest.raises(ValueError, match="must be odd"):
        smoother_grid({**grid, "mean_filter": {"width": [4], "passes": [1]}})


def test_the_report_names_the_smoothers_settings_it_used():
    from toolpath.reports import smoothing_tables

    chosen = {"mean_filter": {"chosen": {"width": 3, "passes": 2}, "settings": [{"width": 3, "passes": 1}, {
        "width": 3, "passes": 2}, {"width": 5, "passes": 1}]}, "bezier": {"chosen": {"degree": 12}, "settings": [
        {"degree": 5}, {"degree": 12}, {"degree": 16}]}}
    notes = smoothing_tables.smoother_notes({"gear": {"smoother_study": {"windows": 24, "modes": {"tube": chosen}}},
                                             "maple_leaf": {}})
    assert notes == ["gear: the smoothers' settings, chosen per mode as NACOA's count is (lowest mean Fitness on 24 "
                     "validation windows of categories 2-4): bound (tube): mean filter width 3 x 2 pass(es), "
                     "Bezier degree 12."]
    chosen["bezier"]["chosen"] = {"degree": 16}
    edge = smoothing_tables.smoother_notes({"gear": {"smoother_study": {"windows": 24, "modes": {"tube": chosen}}}})
    assert edge[0].endswith("In bound (tube) a setting at an end of its grid won: a heavier or lighter one might do "
                            "better still.")
