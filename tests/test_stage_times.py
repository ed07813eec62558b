"""The stage timer behind `make repro`: stage boundaries from DVC's output, families, the exit code."""

import json
import subprocess
import sys
import time

import pytest

from toolpath.pipeline.stage_times import by_family, end_line, main, stage_seconds, started_at


def test_a_stage_lasts_until_the_next_one_starts():
    events = [(0.0, "Running stage 'generate@gear':\n"), (1.0, "> python ...\n"),
              (2.5, "Running stage 'train@gear':\n"), (9.0, "Running stage 'train@pentagram':\n")]
    seconds = stage_seconds(events, end=10.0)
    assert seconds == {"generate@gear": 2.5, "train@gear": 6.5, "train@pentagram": 1.0}
    assert by_family(seconds) == {"generate": 2.5, "train": 7.5}


def test_a_stage_that_prints_its_end_line_ends_there_and_dvc_work_after_it_is_counted_apart(tmp_path):
    events = [(0.0, "Running stage 'generate@gear':\n"), (1.0, end_line("generate@gear", False, 0.9, "abc") + "\n"),
              (2.5, "Running stage 'train@gear':\n"), (3.0, end_line("train@pentagram", False, 1.0, "x") + "\n"),
              (4.0, end_line("train@gear", True, 1.4, "def") + "\n"),
              (4.5, end_line("train@gear", False, 9, "y") + "\n")]
    # another stage's end line, and a second one of the same stage, are not its end
    assert stage_seconds(events, end=6.0) == {"generate@gear": 1.0, "train@gear": 1.5}
    out = tmp_path / "t.json"
    script = ("import time; print(\"Running stage 'a':\", flush=True); time.sleep(0.2); "
              f"print({end_line('a', False, 0.2, 'r')!r}, flush=True); time.sleep(0.6)")
    assert main(["--out", str(out), "--", sys.executable, "-c", script]) == 0
    written = json.loads(out.read_text())
    assert written["stages"]["a"] < written["total_seconds"] - 0.5  # the time after the end line is DVC's
    assert written["dvc_seconds"] == pytest.approx(written["total_seconds"] - written["stages"]["a"], abs=1e-3)


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


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_a_process_start_is_read_to_a_clock_tick_on_the_wall_clock():
    before = time.time()  # psutil's create_time can be up to 1 s off this clock (boot time in whole seconds)
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(5)"])
    after = time.time()
    try:
        assert before - 0.02 <= started_at(child.pid) <= after + 0.02
    finally:
        child.kill()
        child.wait()
    assert started_at(2 ** 22 + 7) is None  # no such process
