"""The `toolpath` entry point: help, a sub-command, and clear refusals (no traceback)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from toolpath.cli import main


def test_help_lists_the_sub_commands(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "stage-times" in out and "smooth" in out


def test_unknown_sub_command_is_one_clear_error(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["frobnicate"])
    assert exit_info.value.code == 2
    assert "invalid choice: 'frobnicate'" in capsys.readouterr().err


def test_smooth_with_a_missing_input_is_one_line_and_touches_nothing(tmp_path, capsys):
    assert main(["smooth", str(tmp_path / "in.nc"), "-o", str(tmp_path / "out.nc")]) == 2
    assert "in.nc: no such file" in capsys.readouterr().err and not list(tmp_path.iterdir())


def test_stage_times_runs_through_the_entry_point(tmp_path):
    out = tmp_path / "times.json"
    code = main(["stage-times", "--out", str(out), "--", sys.executable, "-c",
                 "print(\"Running stage 'a':\"); print(\"Running stage 'b@x':\")"])
    assert code == 0 and set(json.loads(out.read_text())["stages"]) == {"a", "b@x"}


def test_the_installed_command_starts():
    script = Path(sys.executable).with_name("toolpath")
    if not script.is_file():
        pytest.skip(f"no `toolpath` console script beside {sys.executable} (package not installed in this venv)")
    done = subprocess.run([str(script), "--help"], capture_output=True, text=True)
    assert done.returncode == 0 and "stage-times" in done.stdout and "Traceback" not in done.stderr
