"""Algorithm 1: windows, Table 1 categories, program-level split."""

import numpy as np
import pytest

from test_geometry import plain_local_curvature
from toolpath.gcode import read_text
from toolpath.geometry.labels import categorize, cut_windows, feed_runs, label_program, split_by_program


def test_table1_bounds_inclusive_and_exclusive_ends():
    lc = np.array([0.0, 1.9, 1.90001, 3.49, 3.5, 7.59, 7.6, 40.0])
    assert categorize(lc).tolist() == [1, 1, 2, 2, 3, 3, 4, 4]


def test_labels_equal_plain_python_local_curvature_on_random_windows():
    rng = np.random.default_rng(3)
    xy = rng.normal(scale=[1.0, 0.05], size=(1000, 2)).cumsum(axis=0)
    w = cut_windows(xy, np.arange(1000), size=50, stride=50)
    assert len(w) == 20 and w.windows.dtype == np.float32 and w.windows.shape == (20, 50, 2)
    for k in range(len(w)):
        expected = plain_local_curvature(w.windows[k].astype(float).tolist())
        assert w.local_curvature[k] == pytest.approx(expected, rel=1e-9)
        cat = 1 if expected <= 1.9 else 2 if expected < 3.5 else 3 if expected < 7.6 else 4
        assert w.label[k] == cat
    assert np.allclose(w.windows[:, 0], 0) and np.allclose(w.origin + w.windows[:, -1], xy[49::50], atol=1e-4)


def test_windows_stride_and_tail():
    xy = np.column_stack([np.arange(130.0), np.zeros(130)])
    w = cut_windows(xy, np.arange(130) + 1, size=50, stride=25)
    assert len(w) == 4 and w.first_line.tolist() == [1, 26, 51, 76] and w.unlabelled_points == 5


def test_runs_break_at_rapids_start_at_the_rapid_end_and_drop_repeats():
    text = "G0 X0 Y0\nG1 Z-1\nG1 X1\nX2\nG0 Z5\nG0 X10 Y10\nG1 Z-1\nG1 X11\n"
    runs = feed_runs(read_text(text))
    assert [r[0].tolist() for r in runs] == [[[0, 0], [1, 0], [2, 0]], [[10, 10], [11, 10]]]
    assert runs[0][1].tolist() == [1, 3, 4]


def test_label_program_on_a_zigzag_is_category_4_and_a_line_category_1():
    zig = "G0 X0 Y0\nG1 F100\n" + "".join(f"X{k} Y{k % 2}\n" for k in range(1, 50))
    assert label_program(read_text(zig)).label.tolist() == [4]
    line = "G0 X0 Y0\nG1 F100\n" + "".join(f"X{k}\n" for k in range(1, 50))
    assert label_program(read_text(line)).label.tolist() == [1]


def test_split_is_by_program_stratified_and_seeded():
    rng = np.random.default_rng(0)
    program = np.repeat(np.arange(28), 20)
    labels = rng.integers(1, 5, size=len(program))
    a = split_by_program(program, labels, (0.7, 0.15, 0.15), seed=5)
    assert np.array_equal(a, split_by_program(program, labels, (0.7, 0.15, 0.15), seed=5))
    for p in range(28):
        assert len(set(a[program == p].tolist())) == 1  # a program's windows share one split
    assert [len(np.unique(program[a == k])) for k in range(3)] == [20, 4, 4]  # k = 7 folds of 4 programs
    for k in range(3):
        assert set(labels[a == k].tolist()) == {1, 2, 3, 4}
    with pytest.raises(ValueError, match="add up to 1"):
        split_by_program(program, labels, (0.5, 0.2, 0.2), seed=0)
    with pytest.raises(ValueError, match="cannot fill"):
        split_by_program(program[:100], labels[:100], (0.7, 0.15, 0.15), seed=0)


def test_arc_share_counts_the_points_an_arc_reaches_per_window():
    """60 one-millimetre G1 steps, then a half circle of radius 10 in fine chords.  The run starts at
    X0 (where the rapid left the tool), so the first window (points 0-49) is all lines and the second
    (points 50-99) holds X50-X60, 11 line points, and 39 arc points: share 39/50."""
    from toolpath.gcode import ReaderOptions
    from toolpath.geometry.labels.windows import arc_share

    lines = ["G21 G90 G17", "G0 X0 Y0", "G1 F100"] + [f"X{k}" for k in range(1, 61)] + ["G2 X80 Y0 I10 J0"]
    program = read_text("\n".join(lines) + "\n", options=ReaderOptions(chord_tolerance=0.0005))
    windows = label_program(program, 50, 50)
    share = arc_share(program, 50, 50)
    assert len(share) == len(windows.label) >= 3
    assert share[0] == 0.0 and share[1] == pytest.approx(39 / 50) and share[2] == 1.0


def test_corpus_report_splits_arc_windows_from_line_windows_by_hand():
    from toolpath.models.training.generalise import corpus_report

    y = np.array([1, 1, 2, 3, 1, 4])
    proba = np.eye(4)[np.array([1, 2, 2, 3, 1, 1]) - 1]  # one line window of category 1 and the 4 wrong
    arcs = np.array([0.0, 0.0, 0.0, 0.0, 0.9, 0.6])
    report = corpus_report(y, proba, arcs)
    assert report["all"]["windows"] == 6 and report["all"]["rough_windows"] == 3
    assert report["lines"]["windows"] == 4 and report["lines"]["accuracy"] == 0.75
    assert report["lines"]["per_class"]["1"] == {"count": 2, "recall": 0.5}
    assert report["lines"]["per_class"]["4"] == {"count": 0, "recall": None}
    assert report["arcs"]["windows"] == 2 and report["arcs"]["per_class"]["4"]["recall"] == 0.0
    assert report["arcs"]["majority_accuracy"] == 0.5
