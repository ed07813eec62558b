"""The stage timer behind `make repro`: stage boundaries from DVC's output, families, the exit code."""

import json
import sys

from toolpath.pipeline.stage_times import by_family, main, stage_seconds


def test_a_stage_lasts_until_the_next_one_starts():
    events = [(0.0, "Running stage 'generate@gear':\n"), (1.0, "> python ...\n"),
              (2.5, "Running stage 'train@gear':\n"), (9.0, "Running stage 'train@pentagram':\n")]
    seconds = stage_seconds(events, end=10.0)
    assert seconds == {"generate@gear": 2.5, "train@gear": 6.5, "train@pentagram": 1.0}
    assert by_family(seconds) == {"generate": 2.5, "train": 7.5}


def test_the_command_output_passes_through_and_its_exit_code_is_kept(tmp_path, capsys):
    out = tmp_path / "t.json"
    script = "print(\"Running stage 'a':\"); print('hello'); raise SystemExit(3)"
    assert main(["--out", str(out), "--", sys.executable, "-c", script]) == 3
    assert "hello" in capsys.readouterr().out
    written = json.loads(out.read_text())
    assert written["exit_code"] == 3 and set(written["stages"]) == {"a"} and written["families"]["a"] >= 0


def test_a_command_that_cannot_start_is_named_and_nothing_is_written(tmp_path, capsys):
    out = tmp_path / "t.json"
    assert main(["--out", str(out), "--", str(tmp_path / "no-such-dvc"), "repro"]) == 127
    err = capsys.readouterr().err
    assert "error: cannot run" in err and "no-such-dvc" in err
    assert not out.exists()
