"""Xie & Zhu sequencing: hand-made sheets with known orders, travel and collisions; Eq. 1-6; baselines; G-code."""

import numpy as np
import pytest

from toolpath.gcode import Motion, read_text
from toolpath.gcode.writer import ProgramSpec
from toolpath.shapes.sequencing import Part, Sheet, make_sheet, part_tree, plan_path, run_sheet, s_shaped_regions, score
from toolpath.shapes.sequencing.orderings import gtsp_plan, manual_order, nearest_neighbour_order
from toolpath.shapes.sequencing.program import sheet_program, visit_path
from toolpath.shapes.sequencing.regions import _Geometry, inflexion_part, partial_sort, reverse_rows
from toolpath.shapes.sequencing.transitions import best_transition, candidate_pairs

ALGORITHM = {"expansions": 2, "start_up": True, "max_handling": 6, "neighbours": 6}


def rect(index, x0, y0, w, h, kind="rectangle"):
    return Part(index, kind, np.array([[x0, y0], [x0 + w, y0], [x0 + w, y0 + h], [x0, y0 + h]], dtype=float))


def three_in_a_row():
    return [rect(k, 20.0 * k, 0.0, 10.0, 10.0) for k in range(3)]


# --- parts ----------------------------------------------------------------------------------------

def test_part_is_counter_clockwise_and_measures_its_contour():
    clockwise = Part(0, "square", np.array([[0, 0], [0, 10], [10, 10], [10, 0]], dtype=float))
    assert clockwise.perimeter == pytest.approx(40.0)
    assert clockwise.polygon.exterior.is_ccw
    np.testing.assert_allclose(clockwise.centroid, [5, 5])
    np.testing.assert_allclose(clockwise.positions, [0, 10, 20, 30])
    assert clockwise.contour_distance(5.0, 35.0) == pytest.approx(10.0)  # the shorter way round (Eq. 6)
    loop = clockwise.walk(0.0, 0.0, True)
    assert len(loop) == 5 and np.allclose(loop[0], loop[-1])


def test_a_part_that_is_not_a_simple_polygon_is_refused():
    with pytest.raises(ValueError, match="part 3"):
        Part(3, "bow", np.array([[0, 0], [10, 10], [10, 0], [0, 10]], dtype=float))


# --- Eq. 4-6: exit and entry points ---------------------------------------------------------------

def test_three_squares_in_a_row_give_the_known_order_and_empty_travel():
    parts = three_in_a_row()
    regions = s_shaped_regions(parts, expansions=2)
    assert [p for r in regions for p in r.order] == [0, 1, 2]
    assert [r.up for r in regions] == [True, False, True]  # the cutting direction alternates
    plan = plan_path(parts, [0, 1, 2], [0, 1, 2], [r.up for r in regions])
    s = score(plan, parts, part_tree(parts), feed=600.0)
    # each transition: 10 mm along the square's bottom edge to its corner, then the 10 mm gap
    assert s["empty_travel_mm"] == pytest.approx(40.0)
    assert s["transition_mm"] == pytest.approx(20.0) and s["retrace_mm"] == pytest.approx(20.0)
    assert s["collisions"] == 0 and s["cut_mm"] == pytest.approx(120.0)
    assert s["machining_time_s"] == pytest.approx(60.0 * 160.0 / 600.0)


def test_the_four_candidate_sources_include_edge_points_and_closest_points():
    a, b = rect(0, 0, 0, 10, 10), Part(1, "triangle", np.array([[20, 5], [30, -5], [30, 15]], dtype=float))
    exit_xy, _, entry_xy, entry_s = candidate_pairs(a, b)
    assert len(exit_xy) == len(entry_xy) == len(entry_s)
    # source d) / b): the closest point of the triangle to the square is its vertex (20, 5), and the
    # nearest point of the square's right edge to that vertex is (10, 5), an interior edge point
    gap = np.hypot(*(entry_xy - exit_xy).T)
    best = np.argmin(gap)
    assert gap[best] == pytest.approx(10.0)
    np.testing.assert_allclose(exit_xy[best], [10, 5])


def test_a_line_through_its_own_part_is_refused_by_eq4():
    parts = three_in_a_row()
    choice = best_transition(parts[0], 0.0, parts[1], part_tree(parts), None)
    assert not choice.colliders
    # exit (0, 0) -> (20, 0) would cost 20 too, but runs along square 0's edge: Eq. 4 refuses it
    np.testing.assert_allclose(choice.exit_xy, [10, 0])
    np.testing.assert_allclose(choice.entry_xy, [20, 0])


# --- collisions and their handling (Sec. VI.B) ----------------------------------------------------

def blocked_sheet():
    """A and B left and right of a tall wall C: every straight A -> B line crosses C."""
    return [rect(0, 0, 0, 10, 10), rect(1, 40, 0, 10, 10), rect(2, 20, -30, 10, 70)]


def test_a_crossing_transition_is_detected_and_an_unsearched_part_is_cut_first():
    parts = blocked_sheet()
    tree = part_tree(parts)
    raw = plan_path(parts, [0, 1, 2], [0, 0, 0])
    assert score(raw, parts, tree, 600.0)["collisions"] == 1
    handled = plan_path(parts, [0, 1, 2], [0, 0, 0], handle_collisions=True)
    assert handled.order == [0, 2, 1] and handled.handled["unsearched"] == 1
    assert score(handled, parts, tree, 600.0)["collisions"] == 0


def test_a_searched_part_in_the_region_is_moved_and_its_neighbours_relinked():
    parts = [*blocked_sheet(), rect(3, 0, -60, 10, 10)]  # D below A, cut before the wall
    plan = plan_path(parts, [3, 2, 0, 1], [0, 0, 0, 0], handle_collisions=True)
    assert plan.handled["searched_in_region"] == 1
    assert plan.order == [3, 0, 2, 1]
    s = score(plan, parts, part_tree(parts), 600.0)
    assert s["collisions"] == 0 and s["via_visits"] == 0


def test_a_searched_part_outside_the_region_is_followed_not_recut():
    parts = [*blocked_sheet(), rect(3, 0, -60, 10, 10)]
    # D, A, B in region 1; the wall, cut second, in region 0 (inside the collision area, not the region)
    plan = plan_path(parts, [3, 2, 0, 1], [1, 1, 0, 1], [True, True], handle_collisions=True)
    assert plan.handled["searched_outside"] == 1
    assert [v.part for v in plan.visits if not v.full] == [2]
    s = score(plan, parts, part_tree(parts), 600.0)
    assert s["collisions"] == 0 and s["via_visits"] == 1
    assert s["retrace_mm"] > 20.0  # the followed stretch of the wall counts as empty travel


# --- Eq. 1-3 and the S-shaped sort ----------------------------------------------------------------

def test_eq1_inflexion_part_cutting_up_and_down():
    # A is leftmost; B and C start left of A's right boundary, B below A, C above A
    parts = [rect(0, 0, 40, 20, 20), rect(1, 5, 0, 20, 20), rect(2, 8, 80, 20, 20)]
    geo = _Geometry(parts)
    assert inflexion_part(geo, [0, 1, 2], up=True) == 1  # |S| = 1: the part below
    assert inflexion_part(geo, [0, 1, 2], up=False) == 2  # |S| = 1: the part above
    far = [rect(0, 0, 40, 20, 20), rect(1, 50, 0, 20, 20)]  # B starts right of A: S empty -> A
    assert inflexion_part(_Geometry(far), [0, 1], up=True) == 0
    chain = [rect(0, 0, 80, 20, 20), rect(1, 2, 40, 20, 20), rect(2, 4, 0, 20, 20)]  # |S| = 2: recurse
    assert inflexion_part(_Geometry(chain), [0, 1, 2], up=True) == 2


def test_eq2_reverses_a_row_when_the_next_row_starts_on_its_left():
    parts = [rect(0, 0, 0, 10, 10), rect(1, 30, 0, 10, 10), rect(2, 0, 30, 10, 10), rect(3, 30, 30, 10, 10)]
    geo = _Geometry(parts)
    rows = [[[0], [1]], [[2], [3]]]  # row 2 starts at x = 5, left of row 1's midpoint (x = 20)
    # r_1 is reversed only when Eq. 3 (f2) holds too: with LS = part 0 in r_1 it does not
    assert reverse_rows(geo, rows, ls=0, up=True) == rows
    low = [*parts, rect(4, 0, -40, 10, 10)]  # LS below r_1 entirely: f2 holds, r_1 is reversed
    assert reverse_rows(_Geometry(low), rows, ls=4, up=True) == [[[1], [0]], [[2], [3]]]
    three = [[[0], [1]], [[2], [3]], [[2], [3]]]
    assert reverse_rows(geo, three, ls=0, up=True)[1] == [[3], [2]]


def test_partial_sort_inverts_every_second_inner_column():
    columns = [[1, 2], [3, 4], [5, 6], [7, 8], [9, 10]]
    assert partial_sort(columns) == [[1, 2], [4, 3], [5, 6], [8, 7], [9, 10]]
    assert partial_sort([[1, 2], [3, 4]]) == [[1, 2], [3, 4]]  # first and last stay


def test_regions_cover_every_part_once_with_alternating_direction():
    sheet = small_sheet()
    regions = s_shaped_regions(sheet.parts, expansions=2)
    order = [p for r in regions for p in r.order]
    assert sorted(order) == list(range(len(sheet.parts)))
    assert all(a.up != b.up for a, b in zip(regions, regions[1:], strict=False))


# --- sheets, baselines, program -------------------------------------------------------------------

def small_sheet(n=12, seed=3):
    kinds = {"gear": 1, "pentagram": 1, "maple_leaf": 1, "rectangle": 1, "circle": 1, "ellipse": 1, "hexagon": 1}
    return make_sheet(n, 400.0, 300.0, kinds, (25.0, 70.0), 6.0, 5.0, 0.1, np.random.default_rng(seed))


def test_sheets_are_seeded_non_overlapping_and_round_trip():
    a, b = small_sheet(), small_sheet()
    assert a.to_dict() == b.to_dict()
    polygons = [p.polygon for p in a.parts]
    assert all(polygons[i].distance(polygons[j]) >= 6.0 - 1e-6
               for i in range(len(polygons)) for j in range(i + 1, len(polygons)))
    assert all(p.bounds[0] >= 0 and p.bounds[2] <= 400 and p.bounds[1] >= 0 and p.bounds[3] <= 300 for p in a.parts)
    again = Sheet.from_dict(a.to_dict())
    assert [p.kind for p in again.parts] == [p.kind for p in a.parts]
    with pytest.raises(ValueError, match="too full"):
        make_sheet(40, 100.0, 100.0, {"circle": 1}, (30.0, 40.0), 5.0, 2.0, 0.1, np.random.default_rng(0), attempts=50)


def test_every_method_cuts_every_part_once_and_is_deterministic():
    sheet = small_sheet()
    gtsp = {"points": 4, "solution_limit": 30, "time_limit": 30.0, "metaheuristic": "greedy_descent"}
    first = run_sheet(sheet, ALGORITHM, gtsp, 1200.0)
    second = run_sheet(sheet, ALGORITHM, gtsp, 1200.0)
    for method, outcome in first.items():
        assert sorted(outcome.plan.order) == list(range(len(sheet.parts))), method
        assert outcome.scores == second[method].scores, method
    assert first["s_shaped"].scores["collisions"] <= first["s_shaped_no_avoidance"].scores["collisions"]
    assert first["gtsp"].scores["retrace_mm"] == 0.0  # it leaves each part where it entered


def test_manual_order_is_a_serpentine_of_rows():
    parts = [rect(0, 50, 0, 10, 10), rect(1, 0, 2, 10, 10), rect(2, 25, 40, 10, 10), rect(3, 0, 41, 10, 10)]
    order, rows = manual_order(parts)
    assert order == [1, 0, 2, 3] and rows == [0, 0, 1, 1]  # first row left to right, second right to left


def test_nearest_neighbour_and_gtsp_on_three_in_a_row():
    parts = three_in_a_row()
    assert nearest_neighbour_order(parts, part_tree(parts)) == [0, 1, 2]
    plan, facts = gtsp_plan(parts, points=4, solution_limit=20, time_limit=30.0)
    assert not facts["time_capped"]
    assert plan.order in ([0, 1, 2], [2, 1, 0])
    # it leaves each part where it entered: 10 mm gap, then the middle square's width plus 10 mm
    assert facts["objective_mm"] == pytest.approx(30.0)


def test_sheet_program_reads_back_as_one_continuous_feed_path():
    sheet = small_sheet(8)
    gtsp = {"points": 4, "solution_limit": 10, "time_limit": 30.0, "metaheuristic": "greedy_descent"}
    plan = run_sheet(sheet, ALGORITHM, gtsp, 1200.0, methods=["s_shaped"])["s_shaped"].plan
    text = sheet_program(plan, sheet.parts, ProgramSpec(decimals=4), -2.0, "test sheet")
    program = read_text(text, "sheet.nc")
    at_depth = program.points[:, 2] == -2.0
    assert (program.kinds[at_depth] == Motion.FEED).all()  # continuous cut: no rapid while down
    xy = program.points[at_depth, :2]
    travelled = np.hypot(*np.diff(xy, axis=0).T).sum()
    s = score(plan, sheet.parts, part_tree(sheet.parts), 1200.0)
    assert travelled == pytest.approx(s["cut_mm"] + s["empty_travel_mm"], rel=1e-4)
    assert text.count("(visit ") == len(plan.visits)
    for visit in plan.visits:  # each visit starts at its entry point
        np.testing.assert_allclose(visit_path(sheet.parts[visit.part], visit)[0], visit.entry_xy, atol=1e-6)


def test_report_tables_set_ours_beside_the_paper():
    from toolpath.reports import sequencing as sequencing_report

    metrics = {"sheets": {"58": {
        "manual": {"empty_travel_mm": 10000.0, "collisions": 3, "optimisation_rate_pct": 0.0},
        "s_shaped": {"empty_travel_mm": 8000.0, "collisions": 0, "optimisation_rate_pct": 20.0},
        "s_shaped_no_avoidance": {"empty_travel_mm": 8500.0, "collisions": 2, "optimisation_rate_pct": 15.0}}},
        "expansion": {"2": {"empty_travel_mm": 8000.0, "collisions": 0}}}
    timing = {"58": {"s_shaped": {"seconds": 1.5}, "s_shaped_no_avoidance": {"seconds": 1.0}}}
    table1 = sequencing_report.sequencing_table(metrics, timing).markdown()
    assert "| 58 | yes | 0 (1) | 10000 (10650) | 8000 (8021) | 1.50 (544.00) | 20.0 (24.0) | -4.0 |" in table1
    assert "| 58 | no | 2 (2) | 10000 (10650) | 8500 (8134) | 1.00 (604.00) | 15.0 (23.6) | -8.6 |" in table1
    baselines = sequencing_report.baselines_table(metrics).markdown()
    assert "| s_shaped | **8000 / 0** |" in baselines and "| manual | 10000 / 3 |" in baselines
    assert "| 2 | 8000 | 0 |" in sequencing_report.expansion_table(metrics, 58).markdown()
