"""The folder benchmark's reader, written apart from toolpath.gcode: hand cases (a square, a full circle,
an R quarter circle, inches, incremental moves), the two-sided distance, and one folder end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from toolpath.bench.programs import STEP, Unfollowed, check, feed_paths, measure, two_sided
from toolpath.bench.programs import _changed_distance as check_distance


def test_a_square_is_its_four_corners_and_a_rapid_ends_the_run():
    [run] = feed_paths("G21 G90\nG0 X0 Y0\nG1 X1 F100\nY1\nX0\nY0\nG0 X5\nM30\nG1 X9\n")
    assert np.array_equal(run, [[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]])


def test_a_full_circle_without_an_end_point_and_an_r_quarter_circle():
    [circle] = feed_paths("G21 G90\nG0 X0 Y0\nG2 I1 J0 F100\n")
    assert np.abs(np.hypot(circle[:, 0] - 1, circle[:, 1]) - 1).max() < 1e-12
    assert circle[:, 0].max() == pytest.approx(2.0, abs=1e-6) and np.array_equal(circle[-1], [0, 0])
    [quarter] = feed_paths("G21 G90\nG0 X1 Y0\nG3 X0 Y1 R1 F100\n")  # counter-clockwise about the origin
    assert np.abs(np.hypot(*quarter.T) - 1).max() < 1e-12 and quarter[:, 0].min() >= -1e-12


def test_inches_and_incremental_moves():
    [run] = feed_paths("G20 G91\nG0 X0 Y0\nG1 X1 F10\nX1\n")
    assert np.allclose(run, [[0, 0], [25.4, 0], [50.8, 0]])


def test_what_it_does_not_follow_is_unchecked_not_passed():
    with pytest.raises(Unfollowed):
        feed_paths("G21\nG1 X[1+1]\n")
    assert check("G21\nG41 D1\nG1 X1\n", "G21\nG41 D1\nG1 X1\n") == {"checked": False, "why": "G41"}
    with pytest.raises(Unfollowed, match=r"grbl \$H"):
        feed_paths("G21\n$H\nG1 X1\n")


def test_an_xz_half_circle_projects_onto_its_diameter_and_program_numbers_and_grbl_reports_are_read_past():
    # G18: the plane's axes are (Z, X); G2 from X0 Z0 about X1 Z0 to X2 Z0 passes Z = +1 (clockwise seen from +Y)
    [run] = feed_paths("O1006\n$$\n?\nG21 G90\nG0 X0 Y3 Z0\nG18 G2 X2 Z0 I1 K0 F100\n")
    assert np.allclose(run[:, 1], 3.0) and run[:, 0].min() >= -1e-12 and run[-1] == pytest.approx([2.0, 3.0])
    assert len(run) > 100  # sampled along the arc, not one chord


def test_the_two_sided_distance_of_a_line_and_its_shifted_copy():
    line = np.array([[0.0, 0.0], [10.0, 0.0]])
    assert two_sided(line, line + [0.0, 0.004]) == pytest.approx(0.004, abs=1e-9)
    shorter = np.array([[0.0, 0.0], [9.0, 0.0]])  # one-sided it would be 0: the far end counts
    assert two_sided(line, shorter) == pytest.approx(1.0, abs=STEP)


def test_a_folder_end_to_end(tmp_path):
    rng = np.random.default_rng(0)
    rough = ["G21 G90", "G0 X0 Y0", "G1 F300"] + [f"G1 X{0.1 * k:.3f} Y{0.05 * rng.standard_normal():.3f}"
                                                  for k in range(1, 200)] + ["M30"]
    (tmp_path / "rough.nc").write_text("\n".join(rough) + "\n")
    (tmp_path / "printer.gcode").write_text("G21\nG1 X1 E5\n")  # an extruder: refused, as LinuxCNC refuses it
    (tmp_path / "notes.txt").write_text("not a program")
    result = measure(tmp_path, units=None)
    assert set(result["programs"]) == {"rough.nc", "printer.gcode"}
    assert result["programs"]["printer.gcode"]["exit"] == 1
    checked = result["programs"]["rough.nc"]["check"]
    assert checked["checked"] and checked["runs_match"] and 0 < checked["largest_distance_mm"] <= 0.01 + STEP / 2
    assert json.dumps(result)  # what the benchmark writes


def test_only_the_changed_stretches_are_sampled_and_the_figure_is_kept():
    run = np.column_stack([np.arange(0.0, 100000.0, 1.0), np.zeros(100000)])  # 100 m: sampled whole, 1e8 points
    moved = run.copy()
    moved[500, 1], moved[90000, 1] = 0.003, -0.007
    assert check_distance(run, moved) == pytest.approx(0.007, abs=STEP / 2)
