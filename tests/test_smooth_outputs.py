"""``toolpath smooth`` never destroys an input (issue 42, "Lost data"): every output path is checked
against the input and each other before anything is written; the input is replaced last; a second
``--in-place`` keeps the first backup; links, FIFOs and devices are refused; SIGINT and SIGTERM leave the
input intact and no temporary file behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from test_smooth import _run, noisy_program


@pytest.fixture
def work(tmp_path):
    program = tmp_path / "prog.nc"
    program.write_text(noisy_program())
    return tmp_path, program


def _only(folder, *names):
    """The folder holds exactly these names (no temporary file left)."""
    assert sorted(p.name for p in folder.iterdir()) == sorted(names)


@pytest.mark.parametrize(("name", "args", "message"), [
    ("prog.json", ["-o", "out.nc", "--report", "prog.json"], "--report would overwrite the input program"),
    ("prog.json", ["--in-place", "--report", "prog.json"], "--report would overwrite the input program"),
    ("prog.png", ["-o", "out.nc", "--plot", "{prog}"], "--plot would overwrite the input program"),
    ("prog.nc", ["-o", "same.json", "--report", "same.json"], "named both as the output and the report"),
    ("prog.nc", ["-o", "out.nc", "--report", "p.svg", "--plot", "p.svg"], ".json or .html"),
    ("prog.nc", ["-o", "out.nc", "--report", "r.html", "--plot", "r.html"], ".png or .svg"),
    ("prog.nc", ["--in-place", "--report", "nodir/r.json"], "nodir: no such directory"),
])
def test_outputs_that_would_destroy_a_file_are_refused_before_anything_is_written(tmp_path, name, args, message):
    program = tmp_path / name
    program.write_text(noisy_program())
    original = program.read_bytes()
    done = _run(program, *[a.format(prog=program) for a in args], cwd=tmp_path)
    assert done.returncode == 2 and message in done.stderr, done.stderr
    assert program.read_bytes() == original
    _only(tmp_path, name)


def test_a_report_named_as_the_input_through_another_path_is_refused(work):
    folder, program = work
    (folder / "link.json").symlink_to(program)
    done = _run(program, "-o", "out.nc", "--report", "link.json", cwd=folder)
    assert done.returncode == 2 and "would overwrite the input" in done.stderr
    os.link(program, folder / "hard.nc")  # another name of the same file
    assert _run(program, "-o", "hard.nc", "--force", cwd=folder).returncode == 2
    assert program.read_text() == noisy_program()


@pytest.mark.parametrize("kind", ["symlink", "fifo", "folder"])
def test_an_output_place_holding_a_link_fifo_or_folder_is_never_replaced(work, kind):
    folder, program = work
    target = folder / "out.nc"
    if kind == "symlink":
        (folder / "elsewhere.nc").write_text("keep")
        target.symlink_to(folder / "elsewhere.nc")
    elif kind == "fifo":
        os.mkfifo(target)
    else:
        target.mkdir()
    done = _run(program, "-o", target, "--force", cwd=folder)
    assert done.returncode == 2 and ("never replaced" in done.stderr or "symbolic link" in done.stderr), done.stderr
    assert target.is_symlink() if kind == "symlink" else (target.is_dir() if kind == "folder" else target.is_fifo())


def test_a_second_in_place_run_keeps_the_first_backup(work):
    folder, program = work
    original = program.read_bytes()
    assert _run(program, "--in-place", "--method", "mean", cwd=folder).returncode == 0
    smoothed = program.read_bytes()
    done = _run(program, "--in-place", "--force", "--method", "mean", cwd=folder)  # --force is not for backups
    assert done.returncode == 2 and "--force-backup" in done.stderr
    assert (folder / "prog.nc.bak").read_bytes() == original and program.read_bytes() == smoothed
    assert _run(program, "--in-place", "--force-backup", "--method", "mean", cwd=folder).returncode == 0
    assert (folder / "prog.nc.bak").read_bytes() == smoothed  # asked for: the backup is this input's copy


def test_an_existing_report_is_replaced_only_with_force(work):
    folder, program = work
    (folder / "r.json").write_text("keep me")
    assert _run(program, "-o", "out.nc", "--report", "r.json", cwd=folder).returncode == 2
    assert (folder / "r.json").read_text() == "keep me" and not (folder / "out.nc").exists()
    assert _run(program, "-o", "out.nc", "--report", "r.json", "--force", "--method", "mean",
                cwd=folder).returncode == 0
    assert (folder / "r.json").read_text().startswith("{")


@pytest.mark.parametrize(("signum", "code", "said"), [(signal.SIGTERM, 143, "terminated"),
                                                       (signal.SIGINT, 130, "interrupted")])
def test_a_signal_leaves_the_input_intact_and_no_temporary_file(tmp_path, signum, code, said):
    program = tmp_path / "big.nc"
    program.write_text("G21 G90\nG0 X0 Y0\nG1 F500\n" + "".join(
        f"G1 X{0.01 * k:.3f} Y{0.02 * ((k * 7919) % 13 == 0):.3f}\n" for k in range(1, 400_000)))
    original = program.read_bytes()
    process = subprocess.Popen([sys.executable, "-m", "toolpath.cli", "smooth", str(program), "--in-place"],
                               cwd=tmp_path, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not any(p.name.startswith(".big.nc.") for p in tmp_path.iterdir()):  # it has started writing
        assert process.poll() is None and time.monotonic() < deadline, "the run ended before it could be stopped"
        time.sleep(0.02)
    process.send_signal(signum)
    _, err = process.communicate(timeout=60)
    assert process.returncode == code and err.strip().splitlines() == [f"toolpath smooth: {said}, no file written"]
    assert program.read_bytes() == original
    _only(tmp_path, "big.nc")


def test_lines_changed_counts_the_lines_written_differently(work):
    """At a tolerance below the written precision every moved number rounds back to its own text: the
    output is the input, byte for byte, and the summary says no line changed."""
    folder, program = work
    done = _run(program, "-o", "out.nc", "--report", "r.json", "--tolerance", "0.00071", "--method", "mean",
                cwd=folder)
    assert done.returncode == 0, done.stderr
    changed = sum(a != b for a, b in zip(program.read_text().splitlines(), (folder / "out.nc").read_text().splitlines(),
                                         strict=True))
    assert json.loads((folder / "r.json").read_text())["lines_changed"] == changed


def test_a_seed_out_of_range_is_a_usage_error(work):
    folder, program = work
    done = _run(program, "-o", "out.nc", "--seed", "-5", cwd=folder)
    assert done.returncode == 2 and "--seed -5" in done.stderr and not (folder / "out.nc").exists()


@pytest.mark.parametrize(("predict", "said"), [
    (lambda X: 1 / 0, "division by zero"),
    (lambda X: np.zeros((len(X), 3)), "not two categories 1-4"),
    (lambda X: np.zeros(len(X), int), "not two categories 1-4"),
])
def test_a_model_that_is_no_window_classifier_is_the_files_problem(predict, said):
    from toolpath.smooth.command import InputError, checked

    with pytest.raises(InputError, match=rf"m\.onnx: not a classifier of 50-point windows .*{said}"):
        checked(predict, "m.onnx")
    rule = checked(lambda X: np.ones(len(X), int), "rule")
    assert rule(np.zeros((3, 50, 2))).tolist() == [1, 1, 1]


def test_a_temporary_is_noted_for_removal_before_it_exists(tmp_path, monkeypatch):
    """A signal's handler removes what PENDING names: the temporary's name is there before the file is
    made (a signal in between once left the file behind in the suite) and gone once it is renamed."""
    from toolpath.smooth import outputs

    made = []
    real_open = os.open

    def noting_open(name, *args):
        made.append((name, name in outputs.PENDING, os.path.exists(name)))
        return real_open(name, *args)

    monkeypatch.setattr(outputs.os, "open", noting_open)
    with outputs.atomic(tmp_path / "out.nc") as fh:
        fh.write(b"G0 X0\n")
    assert [(noted, existed) for _, noted, existed in made] == [(True, False)]
    assert not outputs.PENDING and (tmp_path / "out.nc").read_bytes() == b"G0 X0\n"
    _only(tmp_path, "out.nc")
