"""The G-code benchmark's runners work (no timing asserted: figures live in reports/bench/gcode.json)."""

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
