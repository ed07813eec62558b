"""`toolpath smooth`: only the moved G1 numbers change, the whole path stays within the two-sided
tolerance, and bad paths, options and input end in one line and a non-zero exit."""

import contextlib
import io
import json
import os
import re
import subprocess
import sys
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import REPO
from toolpath.gcode import read_text
from toolpath.gcode.edit import substitute_plain_xy, substitute_xy
from toolpath.geometry.hausdorff import hausdorff
from toolpath.geometry.labels.windows import feed_runs
from toolpath.models.rule import LocalCurvatureRule
from toolpath.smooth import command as cli
from toolpath.smooth.rewrite import RewriteOptions, smooth_program

CORPUS = REPO.parent / "shared" / "gcode-corpus"
NUMBER = re.compile(r"([XY])\s*-?\d*\.?\d+")


def noisy_program(n: int = 160, amplitude: float = 0.05, seed: int = 0, ending: str = "\n", extras: bool = True) -> str:
    """A straight 40 mm cut with CAM-like noise on Y, plus the lines a rewrite must keep."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 40.0, n)
    y = amplitude * rng.standard_normal(n)
    lines = ["%", "(noisy line)", "G21 G90 G17", "S12000 M3", "G0 X0 Y0", "G1 Z-1 F300"]
    for k in range(1, n):
        words = f"X{x[k]:.3f} Y{y[k]:.3f}"
        if extras and k % 37 == 0:
            lines.append(f"N{k} G1 {words} F{1000 + k} (feed change)")
        elif extras and k % 53 == 0:
            lines += ["", "M8 ; coolant", f"G1 {words}"]
        else:
            lines.append(f"G1 {words}")
    lines += ["G0 Z5", "M5", "M30", "%"]
    return ending.join(lines) + ending


def _smooth(text: str, tolerance: float = 0.01, method: str = "mean_filter"):
    program = read_text(text, "noisy.nc")
    options = RewriteOptions(tolerance=tolerance, smoothing=cli.SMOOTHING, method=method, mapping=cli.DISPATCH)
    return program, smooth_program(program, LocalCurvatureRule().predict, options)


def _whole_path_deviation(before: str, after: str) -> float:
    a = feed_runs(read_text(before, "a"))
    b = feed_runs(read_text(after, "b"))
    assert len(a) == len(b)
    # a run that came back point for point the same lies at distance 0: skip its (quadratic) distance
    return max((0.0 if np.array_equal(p[0], q[0]) else float(hausdorff(p[0], q[0])) for p, q in zip(a, b, strict=True)),
               default=0.0)


@pytest.mark.parametrize("ending", ["\n", "\r\n"])
def test_only_the_moved_numbers_change_and_the_path_stays_within_tolerance(ending):
    text = noisy_program(ending=ending)
    program, result = _smooth(text)
    assert result.changed_lines, "the noisy line has rough windows to smooth"
    old, new = text.splitlines(keepends=True), result.text.splitlines(keepends=True)
    assert len(old) == len(new)
    changed = {i + 1 for i, (a, b) in enumerate(zip(old, new, strict=True)) if a != b}
    assert changed == set(result.changed_lines)
    for line in changed:  # same words, comments, N/F, ending: only the X/Y numbers differ
        assert NUMBER.sub(r"\1#", old[line - 1]) == NUMBER.sub(r"\1#", new[line - 1])
    assert _whole_path_deviation(text, result.text) <= 0.01 + 1e-9
    smoothed = [w for w in result.windows if w.status == "smoothed"]
    assert smoothed and all(w.curvature_after < w.curvature_before for w in smoothed)
    assert max(w.deviation_mm for w in result.windows) <= 0.01


def test_a_program_without_rough_windows_comes_back_byte_identical():
    text = noisy_program(amplitude=0.0)
    _, result = _smooth(text)
    assert result.text == text and not result.changed_lines


def test_a_line_relying_on_a_modal_x_after_the_stretch_keeps_its_point():
    rng = np.random.default_rng(3)
    lines = ["G21 G90", "G0 X0 Y0", "G1 Z-1 F200"]
    lines += [f"G1 X{k * 0.5:.3f} Y{0.02 * rng.standard_normal():.3f}" for k in range(1, 60)]
    lines += ["G1 Y3.000", "G1 X40.000 Y3.000", "M30"]  # 'G1 Y3' relies on the modal X of the line before
    text = "\n".join(lines) + "\n"
    program, result = _smooth(text)
    reread = read_text(result.text, "out")
    line = lines.index("G1 Y3.000") + 1
    k = int(np.flatnonzero(program.lines_of_points == line)[0])
    assert np.array_equal(reread.points[k], program.points[k])


def test_substitution_keeps_everything_but_the_numbers():
    assert substitute_xy("n10 g1 x1.000 y2.000 f300 (cut) ; end\r\n", {"X": "1.004", "Y": "1.998"}) == \
        "n10 g1 x1.004 y1.998 f300 (cut) ; end\r\n"
    assert substitute_xy("G1 Y2.000 (x stays modal)\n", {"X": "0.500", "Y": "2.010"}) == \
        "G1 X0.500 Y2.010 (x stays modal)\n"
    assert substitute_xy("G1 X1.0\n", {"X": "1.1", "Y": "0.2"}) == "G1 X1.1 Y0.2\n"


@settings(max_examples=100, deadline=None)
@given(words=st.permutations(["X", "Y", "G1", "Z", "F", "N"]), keep=st.lists(st.booleans(), min_size=6, max_size=6),
       numbers=st.lists(st.from_regex(r"[+-]?(\d{1,4}(\.\d{0,4})?|\.\d{1,3})", fullmatch=True), min_size=6, max_size=6),
       lower=st.booleans(), ending=st.sampled_from(["\n", "\r\n", ""]), blank=st.sampled_from([" ", "", "\t"]))
def test_the_plain_line_substitution_is_the_general_one(words, keep, numbers, lower, ending, blank):
    # the scanner's plain lines: letters G X Y Z F N, each at most once, each with a plain number
    parts = [w if w == "G1" else w + n for w, n, k in zip(words, numbers, keep, strict=True) if k or w in "XY"]
    line = blank.join(parts) + ending
    line = line.lower() if lower else line
    for drop in ("", "X", "Y"):
        text = re.sub(rf"{drop}[+-]?[\d.]+\s?", "", line, flags=re.I) if drop else line
        assert substitute_plain_xy(text, "1.250", "-0.500") == substitute_xy(text, {"X": "1.250", "Y": "-0.500"})


def test_tolerance_finer_than_the_numbers_is_refused():
    from toolpath.gcode import GCodeError

    with pytest.raises(GCodeError, match="finer than"):
        _smooth(noisy_program(), tolerance=0.0005)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), amplitude=st.floats(0.0, 0.05), n=st.integers(30, 200),
       tolerance=st.sampled_from([0.005, 0.01, 0.05]), method=st.sampled_from(["mean_filter", "bezier", "dispatch"]))
def test_property_only_rough_window_lines_change_and_the_output_reads_back_within_tolerance(
        seed, amplitude, n, tolerance, method):
    text = noisy_program(n=n, amplitude=amplitude, seed=seed)
    program, result = _smooth(text, tolerance, "mean_filter" if method == "dispatch" else method)
    rough_lines = set()
    for w in result.windows:
        if w.category >= 2:
            rough_lines.update(range(w.first_line, w.last_line + 1))
    old, new = text.splitlines(keepends=True), result.text.splitlines(keepends=True)
    assert len(old) == len(new)
    assert all(a == b for i, (a, b) in enumerate(zip(old, new, strict=True)) if i + 1 not in rough_lines)
    assert _whole_path_deviation(text, result.text) <= tolerance + 1e-9


def test_defaults_are_the_pipelines():
    from omegaconf import OmegaConf

    params = OmegaConf.to_container(OmegaConf.load(REPO / "params.yaml"))
    opt = params["optimize"]
    # the product keeps its own size, chosen for speed (issue 40): the pipeline runs the paper's N = 1000
    own = ("_target_", "population", "generations")
    assert {k: v for k, v in opt["nacoa"].items() if k not in own} == \
        {k: v for k, v in cli.SMOOTHING["nacoa"].items() if k not in own}
    assert cli.SMOOTHING["nacoa"]["population"] < opt["nacoa"]["population"]
    for key in ("mean_filter", "bezier", "penalty_weight", "box"):
        assert opt[key] == cli.SMOOTHING[key]
    assert {int(k): v for k, v in opt["dispatch"].items()} == cli.DISPATCH
    assert {k: v for k, v in params["feedrate"]["machine"].items() if k != "_target_"} == cli.MACHINE
    assert params["feedrate"]["blend_tolerance"] == cli.BLEND_TOLERANCE


@dataclass
class Done:
    returncode: int
    stderr: str


def _run(*args, cwd=None) -> Done:
    """``toolpath smooth ARGS`` in this process (a subprocess per call would cost seconds of start-up),
    from ``cwd``; its exit code and standard error."""
    err, here = io.StringIO(), os.getcwd()
    try:
        os.chdir(cwd or here)
        with contextlib.redirect_stderr(err):
            try:
                code = cli.main([str(a) for a in args])
            except SystemExit as exit_info:  # argparse's own errors
                code = exit_info.code
    finally:
        os.chdir(here)
    return Done(int(code), err.getvalue())


def test_the_module_runs_as_a_command(tmp_path):
    done = subprocess.run([sys.executable, "-m", "toolpath.cli", "smooth", str(tmp_path / "none.nc"), "-o",
                           str(tmp_path / "o.nc")], capture_output=True, text=True)
    assert done.returncode == 2 and "none.nc: no such file" in done.stderr and "Traceback" not in done.stderr


@pytest.fixture
def rough_file(tmp_path):
    path = tmp_path / "rough.nc"
    path.write_text(noisy_program())
    return path


def test_cli_writes_the_program_and_a_json_report(rough_file, tmp_path):
    out, report = tmp_path / "out.nc", tmp_path / "r.json"
    done = _run(rough_file, "-o", out, "--report", report, "--method", "mean")
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    data = json.loads(report.read_text())
    assert data["largest_deviation_mm"] <= 0.01 and data["lines_changed"] > 0
    assert data["machining_time_s"]["before"] > 0 and data["machining_time_s"]["after"] > 0
    assert sum(data["windows"]["per_category"].values()) == data["windows"]["total"] == len(data["window_rows"])
    assert rough_file.read_text() == noisy_program()  # the input is untouched
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask  # a plain new file, not mkstemp's private one
    html = tmp_path / "r.html"
    assert _run(rough_file, "-o", tmp_path / "out2.nc", "--report", html, "--method", "mean").returncode == 0
    assert "<svg" in html.read_text() and "{&#x27;" not in html.read_text()  # no Python dict shown as is
    assert (tmp_path / "out2.nc").read_bytes() == out.read_bytes()  # same seed, same bytes
    again = tmp_path / "r2.html"
    done = _run(rough_file, "-o", tmp_path / "out2.nc", "--force", "--report", again, "--method", "mean")
    assert done.returncode == 0
    assert again.read_bytes() == html.read_bytes()  # the drawing too: no date, fixed element ids
    rows = [line for line in report.read_text().splitlines() if line.startswith('    {"run": ')]
    assert len(rows) == len(data["window_rows"])  # one line per window row


def test_cli_in_place_keeps_a_backup(rough_file):
    original = rough_file.read_bytes()
    done = _run(rough_file, "--in-place", "--method", "mean")
    assert done.returncode == 0, done.stderr
    assert rough_file.with_name("rough.nc.bak").read_bytes() == original and rough_file.read_bytes() != original
    again = _run(rough_file, "--in-place")  # the backup exists: refused, nothing touched
    assert again.returncode == 2 and "backup" in again.stderr


@pytest.mark.parametrize("args, message", [
    (["missing.nc", "-o", "out.nc"], "no such file"),
    (["/dev/zero", "-o", "out.nc"], "/dev/zero: not a regular file"),
    ([".", "-o", "out.nc"], ".: not a regular file"),
    (["{rough}", "-o", "{rough}"], "that is the input"),
    (["{rough}"], "-o OUT"),
    (["{rough}", "-o", "out.nc", "--tolerance", "-1"], "positive"),
    (["{rough}", "-o", "out.nc", "--tolerance", "nan"], "positive"),
    (["{rough}", "-o", "out.nc", "--classifier", "nothing.pt"], "no such model file"),
    (["{rough}", "-o", "out.nc", "--report", "r.txt"], ".json or .html"),
    (["{rough}", "-o", "out.nc", "--method", "magic"], "invalid choice"),
    (["{rough}", "-o", "no/such/dir/out.nc"], "no such directory"),
])
def test_cli_refuses_bad_paths_and_options_in_one_line(rough_file, tmp_path, args, message):
    done = _run(*[a.format(rough=rough_file) for a in args], cwd=tmp_path)
    assert done.returncode == 2 and message in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "out.nc").exists()


def test_cli_refuses_an_existing_output_unless_forced(rough_file, tmp_path):
    out = tmp_path / "out.nc"
    out.write_text("keep me")
    assert _run(rough_file, "-o", out).returncode == 2 and out.read_text() == "keep me"
    assert _run(rough_file, "-o", out, "--force", "--method", "mean").returncode == 0


def test_cli_names_file_and_line_of_unsupported_input_and_of_a_corrupt_model(tmp_path, rough_file):
    bad = tmp_path / "bad.nc"
    bad.write_text("G21\nG2 X1 Y0 R0.1 F100\n")  # an R arc shorter than half its chord: LinuxCNC refuses it too
    done = _run(bad, "-o", tmp_path / "out.nc")
    assert done.returncode == 1 and f"{bad}:2:" in done.stderr and "Traceback" not in done.stderr
    garbage = tmp_path / "model.pt"
    garbage.write_bytes(b"not a checkpoint")
    done = _run(rough_file, "-o", tmp_path / "out.nc", "--classifier", garbage)
    assert done.returncode == 1 and "model.pt" in done.stderr and "Traceback" not in done.stderr
    garbage = tmp_path / "model.onnx"
    garbage.write_bytes(b"not an onnx graph")
    done = _run(rough_file, "-o", tmp_path / "out.nc", "--classifier", garbage, "--runtime", "onnxruntime")
    assert done.returncode == 1 and "model.onnx: not a model onnxruntime can run" in done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "out.nc").exists()


@pytest.mark.skipif(not CORPUS.is_dir(), reason="../shared/gcode-corpus is absent (real CAM programs)")
@pytest.mark.parametrize("name", sorted(p.name for p in CORPUS.glob("*")
                                        if p.suffix in (".nc", ".ngc", ".tap", ".gcode")) if CORPUS.is_dir() else [])
def test_every_corpus_program_smooths_within_tolerance(name, tmp_path):
    source = CORPUS / name
    text = source.read_bytes().decode("utf-8", errors="surrogateescape")
    done = _run(source, "-o", tmp_path / name, "--report", tmp_path / "r.json", "--method", "mean", "--units", "mm")
    assert done.returncode == 0, done.stderr
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["largest_deviation_mm"] <= 0.01
    after = (tmp_path / name).read_bytes().decode("utf-8", errors="surrogateescape")
    assert _whole_path_deviation(text, after) <= 0.01 + 1e-9


@pytest.mark.parametrize(("options", "module", "extra"), [
    (["--plot", "p.png"], "matplotlib", "plot"),
    (["--report", "r.html"], "matplotlib", "plot"),
    (["--classifier", "m.pt"], "torch", "models"),
    (["--classifier", "m.onnx"], "onnxruntime", "int8"),
])
def test_an_option_whose_package_is_missing_names_the_extra_and_writes_nothing(tmp_path, monkeypatch, capsys,
                                                                               options, module, extra):
    import importlib.util

    program = tmp_path / "in.nc"
    program.write_text("G21 G90\nG1 X0 Y0 F100\n" + "".join(f"G1 X{i} Y{(i % 2) * 0.3}\n" for i in range(1, 80)))
    for name in ("m.pt", "m.onnx"):
        (tmp_path / name).write_bytes(b"model")
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == module else real(name, *a))
    monkeypatch.chdir(tmp_path)
    assert cli.main(["in.nc", "-o", "out.nc", *options]) == 2
    assert f"pip install 'toolpath-lab[{extra}]'" in capsys.readouterr().err
    assert not (tmp_path / "out.nc").exists()


def test_a_window_that_would_not_gain_is_kept_as_it_was_and_said_so():
    """Every window called rough on a straight, evenly spaced cut: the mean filter cannot lower a
    LocalCurvature of zero, so no window is 'smoothed' and no line changes (issue 43)."""
    text = noisy_program(amplitude=0.0, extras=False)
    program = read_text(text, "straight.nc")
    options = RewriteOptions(tolerance=0.01, smoothing=cli.SMOOTHING, method="mean_filter", mapping=cli.DISPATCH)
    result = smooth_program(program, lambda X: np.full(len(X), 2), options)
    assert result.windows and all(w.status.startswith("kept: no gain") for w in result.windows)
    assert result.text == text and not result.changed_lines
    # and on a rough cut, every window called smoothed is one whose LocalCurvature fell
    _, rough = _smooth(noisy_program())
    assert all(w.curvature_after < w.curvature_before for w in rough.windows if w.status == "smoothed")
