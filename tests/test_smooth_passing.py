"""``toolpath smooth`` passes through what it does not smooth (issue 42): other planes' arcs, splines, canned
cycles, cutter compensation, probing, homing, machine coordinates, O-words, M98.  Each such line is
copied byte for byte, windows where the controller's X or Y is unknown to the reader are kept with
their reason, and smoothing resumes where the position is known again (never after control flow)."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from toolpath.gcode import GCodeError, ReaderOptions, read_text
from toolpath.geometry.hausdorff import hausdorff
from toolpath.geometry.labels.windows import feed_runs
from toolpath.smooth.command import main


def rough(start: float, n: int, seed: int) -> list[str]:
    rng = np.random.default_rng(seed)
    return [f"G1 X{start + 0.1 * k:.3f} Y{0.04 * rng.standard_normal():.3f}" for k in range(1, n)]


def program(construct: list[str]) -> tuple[str, range, range]:
    """A rough cut, the construct, a rough cut again: the text and the 0-based line ranges of the cuts."""
    head = ["G21 G90 G17", "G0 X0 Y0 Z1", "G1 Z-1 F300"]
    first = rough(0.0, 160, 1)
    second = rough(30.0, 160, 2)
    lines = head + first + construct + [RESUME] + second + ["M30"]
    a = range(len(head), len(head) + len(first))
    b = range(len(head) + len(first) + len(construct) + 1, len(lines) - 1)
    return "\n".join(lines) + "\n", a, b


RESUME = "G1 X30.000 Y0.000"  # X and Y in absolute mode: the reader knows the position again
CASES = {  # construct lines, the reason a window holding it gives, whether the second cut is smoothed
    "xz arc": (["G18 G2 X17.000 Z-1.5 I0.5 K0", "G17"], "XZ plane", True),
    "spline": (["G5 X25.000 Y0.500 I1 J1 P1 Q-1"], "G5 spline", True),
    "canned cycle": (["G81 X20.000 Y5.000 Z-2 R1 F100", "X22.000", "G80"], "canned cycle G81", True),
    "cutter compensation": (["G41 D1", "G1 X17.000 Y1.000", "G1 X20.000 Y1.000", "G40"], "cutter compensation G41",
                            True),
    "probing": (["G38.2 Z-5 F50", "G0 Z1"], "probing", True),
    "mach probing": (["G31 Z-5 F50", "G0 Z1"], "G31 probing", True),  # Mach3 / Mach4, pcb2gcode's autoleveller
    "homing": (["G28.2 X0 Y0"], "homing", True),
    "work offset set": (["G10 L20 P0 X0 Y0"], "G10 L20 (work offsets set)", True),
    "tool table set": (["G10 L1 P1 Z-2.5 R1.5"], "G10 L1 (tool table set)", True),
    "stored home unknown": (["G28 X20 Y0"], "never stored", True),
    "machine coordinates": (["G53 G0 Z0"], "G53", True),
    "xz full circle": (["G18 G2 I0.5 K0", "G17"], "XZ plane", True),
    "rotary axis": (["G1 X16.500 Y0.000 A90"], "a move of axis A", True),
    "polar coordinates": (["G1 @2 ^45"], "polar coordinates", True),
    "lathe diameter mode": (["G7"], "G7 (lathe diameter mode", False),
    "o-word": (["o100 call"], "O-word control flow", False),
    "m98": (["M98 P1000"], "M98", False),
}


def _changed(before: list[str], after: list[str], span: range) -> int:
    return sum(before[k] != after[k] for k in span)


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_construct_the_tool_does_not_smooth_is_passed_through(tmp_path, capsys, name):
    construct, reason, resumes = CASES[name]
    text, a, b = program(construct)
    source = tmp_path / "p.nc"
    source.write_text(text)
    code = main([str(source), "-o", str(tmp_path / "out.nc"), "--report", str(tmp_path / "r.json"),
                 "--method", "mean"])
    assert code == 0, capsys.readouterr().err
    before, after = text.splitlines(), (tmp_path / "out.nc").read_text().splitlines()
    assert len(after) == len(before)
    assert [after[k] for k in range(a.stop, a.stop + len(construct))] == construct  # byte for byte
    assert _changed(before, after, a) > 0
    assert (_changed(before, after, b) > 0) == resumes
    assert any(reason in passed for passed in json.loads((tmp_path / "r.json").read_text())["passed_through"])
    # the read paths, cut by cut, within the tolerance both ways
    options = ReaderOptions(pass_through=True)
    for old, new in zip(feed_runs(read_text(text, options=options)),
                        feed_runs(read_text("\n".join(after) + "\n", options=options)), strict=True):
        assert float(hausdorff(old[0], new[0])) <= 0.01 + 1e-9


@pytest.mark.parametrize("text, dialect, said", [
    ("O1006\nG21 G90\nG1 X1. Y0. F300.\nM30\n", "linuxcnc", "pass --dialect fanuc"),
    ("O1006\nG21 G90\nG1 X4 Y0. F300.\nM30\n", "fanuc", "X4: an axis word without a decimal point"),
])
def test_dialects_disagree_on_program_numbers_and_integer_words(tmp_path, capsys, text, dialect, said):
    source = tmp_path / "p.nc"
    source.write_text(text)
    assert main([str(source), "-o", str(tmp_path / "out.nc"), "--dialect", dialect]) == 1
    assert said in capsys.readouterr().err and not (tmp_path / "out.nc").exists()


def test_a_fanuc_program_number_and_whole_zeros_are_read_in_the_fanuc_dialect(tmp_path):
    source = tmp_path / "p.nc"
    source.write_text("O1006 (PART)\nG21 G90\nG0 X0 Y0\nG1 X4. Y0. F300.\nM30\n")
    assert main([str(source), "-o", str(tmp_path / "out.nc"), "--dialect", "fanuc"]) == 0
    assert (tmp_path / "out.nc").read_bytes() == source.read_bytes()


@pytest.mark.parametrize("construct, reason", [
    (["$H"], "grbl $H (homing)"), (["$J=G91 X5 F100"], "grbl $J (jogging)"), (["$RST=#"], "grbl $RST"),
    (["$$", "$I ; build info", "?", "$1=25", "$X"], None),  # reports, a setting, an unlock: nothing moves
])
def test_grbl_system_commands_in_the_grbl_dialect(tmp_path, capsys, construct, reason):
    text, a, b = program(construct)
    source = tmp_path / "p.nc"
    source.write_text(text)
    code = main([str(source), "-o", str(tmp_path / "out.nc"), "--report", str(tmp_path / "r.json"),
                 "--method", "mean", "--dialect", "grbl"])
    assert code == 0, capsys.readouterr().err
    before, after = text.splitlines(), (tmp_path / "out.nc").read_text().splitlines()
    assert [after[k] for k in range(a.stop, a.stop + len(construct))] == construct
    assert _changed(before, after, a) > 0 and _changed(before, after, b) > 0
    passed = json.loads((tmp_path / "r.json").read_text())["passed_through"]
    assert any(reason in p for p in passed) if reason else not any("grbl" in p for p in passed)


@pytest.mark.parametrize("line, accepted", [("$$", False), ("$H", False), ("?", False), ("$1 M3 S1000", True)])
def test_linuxcnc_refuses_grbl_commands_but_reads_its_own_spindle_word(tmp_path, capsys, line, accepted):
    source = tmp_path / "p.nc"
    source.write_text(f"G21 G90\nG0 X0 Y0\n{line}\nG1 X1. Y0. F300.\nM30\n")
    code = main([str(source), "-o", str(tmp_path / "out.nc")])
    assert code == (0 if accepted else 1)
    assert accepted or "p.nc:3:" in (err := capsys.readouterr().err) and "pass --dialect grbl" in err


def test_a_dollar_directive_grbl_does_not_know_is_not_taken_for_a_grbl_command(tmp_path, capsys):
    source = tmp_path / "p.nc"  # a CAM editor's directive, which grbl answers with an error too
    source.write_text("G21 G90\n$AddRegPart 1 X2.925 Y2.005\nG1 X1. Y0. F300.\nM30\n")
    assert main([str(source), "-o", str(tmp_path / "out.nc"), "--dialect", "grbl"]) == 1
    err = capsys.readouterr().err
    assert "p.nc:2:" in err and "--dialect grbl" not in err


def test_integer_words_as_whole_units_in_the_fanuc_dialect_when_asked(tmp_path, capsys):
    text, a, _ = program(["G1 X17 Y0"])  # an integer word mid-program, on a control reading it as 17 mm
    source = tmp_path / "p.nc"
    source.write_text("O0001\n" + text)
    out = tmp_path / "out.nc"
    assert main([str(source), "-o", str(out), "--dialect", "fanuc", "--method", "mean"]) == 1
    assert "pass --whole-integer-words" in capsys.readouterr().err
    assert main([str(source), "-o", str(out), "--dialect", "fanuc", "--whole-integer-words", "--method", "mean"]) == 0
    before, after = source.read_text().splitlines(), out.read_text().splitlines()
    moved = re.fullmatch(r"G1 X(\d+\.\d+) Y(-?\d+\.\d+)", after[a.stop + 1])  # written with its decimal points
    assert moved and math.dist((float(moved[1]), float(moved[2])), (17.0, 0.0)) <= 0.01
    assert _changed(before[1:], after[1:], a) > 0
    options = ReaderOptions(pass_through=True, dialect="fanuc", whole_integer_words=True)
    assert read_text(source.read_text(), options=options).points[:, 0].max() == pytest.approx(45.9)


@pytest.mark.parametrize("name", ["canned cycle", "cutter compensation", "probing", "homing"])
def test_a_window_holding_such_a_line_is_kept_with_its_reason(tmp_path, name):
    construct, reason, _ = CASES[name]
    construct = [line for line in construct if not line.startswith("G0")]  # a rapid would end the feed run
    head = ["G21 G90 G17", "G0 X0 Y0 Z1", "G1 Z-1 F300"]
    text = "\n".join(head + rough(0.0, 30, 1) + construct + [RESUME] + rough(30.0, 60, 2) + ["M30"]) + "\n"
    source = tmp_path / "p.nc"
    source.write_text(text)
    assert main([str(source), "-o", str(tmp_path / "out.nc"), "--report", str(tmp_path / "r.json"),
                 "--method", "mean"]) == 0
    rows = json.loads((tmp_path / "r.json").read_text())["window_rows"]
    kept = [row for row in rows if str(row.get("status", "")).startswith("kept")]
    assert kept and all(reason in row["status"] for row in kept), rows


# LinuxCNC runs each of these (its own nc_files examples hold every kind); the reader follows them as it does
LINUXCNC_READS = {  # program after "G21 G90 G17\nG0 X0 Y0 Z0\nG1 F100\n", where the tool ends (mm)
    "full circle (centre format, no end point)": ("G2 I0.5 J0.5\n", (0.0, 0.0, 0.0)),
    "G53 G0 leaves G0 in effect": ("G53 G0 Z0\nX2 Y3\n", (2.0, 3.0, None)),
    "spindle select, analog output, CSS": ("M3 $1 S1\nM68 E3 Q0\nG96 S200 M3\nG97 S1000\nG8\nG1 X1 Y1\n",
                                           (1.0, 1.0, 0.0)),
    "tool length offset words are not a move": ("G43.1 Z5\nG1 X1 Y2\n", (1.0, 2.0, 0.0)),
    "G5.2 in the YZ plane": ("G19\nG5.2 P1 L3\nY0 Z1 P1\nY2 Z2 P1\nY2 Z0 P1\nY0 Z0 P2\nG5.3\nG17\n",
                             (0.0, 0.0, 0.0)),
    "G5.2 in the XZ plane": ("G18\nG5.2 P1 L3\nX1 Z1 P1\nX2 Z2 P1\nX3 Z0 P1\nG5.3\nG17\n", (3.0, 0.0, 0.0)),
}


@pytest.mark.parametrize("name", sorted(LINUXCNC_READS))
def test_what_linuxcnc_runs_is_read(name):
    text, end = LINUXCNC_READS[name]
    program = read_text("G21 G90 G17\nG0 X0 Y0 Z0\nG1 F100\n" + text + "M2\n",
                        options=ReaderOptions(pass_through=True))
    assert all(e is None or abs(p - e) < 1e-9 for p, e in zip(program.points[-1], end, strict=True))
    if name.startswith("full circle"):  # the whole circle is drawn: its far side is one diameter away
        assert np.hypot(*program.points[:, :2].T).max() == pytest.approx(np.sqrt(2.0), abs=1e-3)
    if name.startswith("G5.2 in the YZ"):  # the curve stays in its plane and bulges towards Y2 Z2
        assert np.abs(program.points[:, 0]).max() == 0 and program.points[:, 2].max() > 0.5


@pytest.mark.parametrize("text, said", [
    ("G1 X1 E5\n", "axis word E is not supported"),  # E is only an M66-M68 channel
    ("G1 X1 A90\n", "axis word A is not supported"),
    ("G1 @1 ^90\n", "polar coordinates (@ ^) are not supported"),
    ("G19\n", "not G19"),
])
def test_without_passing_through_the_reader_still_names_what_it_does_not_follow(text, said):
    with pytest.raises(GCodeError, match=re.escape(said)):
        read_text("G21 G90 G17\nG0 X0 Y0 Z0\nG1 F100\n" + text, "p.nc")
