"""The G-code benchmark's runners work (no timing asserted: figures live in reports/bench/gcode.json)."""

import numpy as np

from toolpath.bench import gcode
from toolpath.gcode import read_text


def test_dense_program_reads_and_every_runner_reports(tmp_path):
    text = gcode.dense_program(300)
    assert len(read_text(text).points) == 303  # the rapid and the plunge, 300 moves, the retract
    path = tmp_path / "dense.nc"
    path.write_text(text)
    for name, (_, code) in gcode.RUNNERS.items():
        out = gcode._run(code, path, 1000)
        assert "error" not in out, (name, out)
        assert out["lines"] >= 300 and out["peak_rss_mb"] > 0


def test_the_smooth_cases_run_end_to_end_in_their_own_process():
    result = gcode.measure(lines=300, cases={"tiny": (300, 0.02, "mean", True, 1)})
    row = result["smooth"]["tiny"]
    assert "error" not in row, row
    assert row["lines"] == 305 and len(row["runs"]) == 1 and row["peak_rss_mb"] > 0


def test_write_dense_writes_the_program_dense_program_describes(tmp_path):
    path = tmp_path / "dense.nc"
    gcode.write_dense(path, 2500, seed=3, spikes=0.0, block=1000)
    program = read_text(path.read_text())
    assert len(program.lines) == 2505 and len(program.points) == 2503
    steps = np.hypot(*np.diff(program.points[2:-1, :2], axis=0).T)
    assert steps.max() < 0.06  # one contour: no jump where the blocks meet
