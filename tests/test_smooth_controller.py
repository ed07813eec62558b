"""``toolpath smooth`` writes lines as the controller reads them (issue 42): a block-deleted line is never
the source of a modal value written elsewhere; a window a ``/`` line touches is kept whole, with its
reason; the whole path holds the tolerance with the block-delete switch off and on."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from test_smooth import _run
from toolpath.gcode import GCodeError, ReaderOptions, read_text
from toolpath.geometry.hausdorff import hausdorff
from toolpath.geometry.labels.windows import feed_runs


def rough_with_block_delete(n: int = 400, seed: int = 1) -> str:
    """A rough straight cut; every 60th move block-deleted and the move after it relying on its modal Y."""
    rng = np.random.default_rng(seed)
    lines = ["G21 G90 G17", "G0 X0 Y0", "G1 F300"]
    for k in range(1, n):
        x, y = 0.1 * k, 0.04 * rng.standard_normal()
        if k % 60 == 0:
            lines.append(f"/G1 X{x:.3f} Y{y:.3f}")
        elif k % 60 == 1 and k > 60:
            lines.append(f"G1 X{x:.3f}")  # Y modal: the block-deleted line's with the switch off
        else:
            lines.append(f"G1 X{x:.3f} Y{y:.3f}")
    return "\n".join(lines + ["M30"]) + "\n"


def _path_distance(before: str, after: str, switch: bool) -> float:
    options = ReaderOptions(block_delete=switch)
    a, b = feed_runs(read_text(before, options=options)), feed_runs(read_text(after, options=options))
    assert len(a) == len(b)
    return max(float(hausdorff(p[0], q[0])) for p, q in zip(a, b, strict=True))


@pytest.mark.parametrize("arcs", [False, True])
def test_block_deleted_lines_and_their_modal_followers_hold_at_both_switch_states(tmp_path, arcs):
    program = tmp_path / "p.nc"
    program.write_text(rough_with_block_delete())
    done = _run(program, "-o", "out.nc", "--report", "r.json", "--method", "mean", *(["--arcs"] if arcs else []),
                cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    before, after = program.read_text(), (tmp_path / "out.nc").read_text()
    assert after != before  # windows away from the `/` lines are smoothed
    for switch in (False, True):
        assert _path_distance(before, after, switch) <= 0.01 + 1e-9, f"block delete {'on' if switch else 'off'}"
    source = before.splitlines()
    kept = [line for k, line in enumerate(source) if line.startswith("/") or source[k - 1].startswith("/")]
    assert len(kept) == 12 and all(line in after.splitlines() for line in kept)  # never given the deleted Y
    rows = json.loads((tmp_path / "r.json").read_text())["window_rows"]
    assert any("block delete" in str(row) for row in rows)


def test_g91_switched_on_inside_a_window_keeps_the_incremental_moves(tmp_path):
    """The absolute mode is checked at every point a stretch would move, not only the window's first (a G91
    inside a window had stopped the run with `internal check failed`)."""
    rng = np.random.default_rng(2)
    lines = ["G21 G90", "G0 X0 Y0", "G1 F300"]
    lines += [f"G1 X{0.1 * k:.3f} Y{0.04 * rng.standard_normal():.3f}" for k in range(1, 75)]
    lines += ["G91"] + [f"G1 X0.100 Y{0.04 * rng.standard_normal():.3f}" for _ in range(40)] + ["G90", "M30"]
    program = tmp_path / "g91.nc"
    program.write_text("\n".join(lines) + "\n")
    done = _run(program, "-o", "out.nc", "--method", "mean", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    after = (tmp_path / "out.nc").read_text().splitlines()
    assert after[after.index("G91"):] == lines[lines.index("G91"):]  # every incremental line byte for byte
    assert after != lines and _path_distance("\n".join(lines) + "\n", "\n".join(after) + "\n", False) <= 0.01 + 1e-9


def system_parameter_program(seed: int = 3) -> list[str]:
    rng = np.random.default_rng(seed)
    lines = ["G21 G90", "G0 X0 Y0", "G1 F300"]
    lines += [f"G1 X{0.1 * k:.3f} Y{0.04 * rng.standard_normal():.3f}" for k in range(1, 130)]
    lines += ["#<x>=#5420 (where the controller stands)", "G1 X[#<x> + 0.1] Y0.02"]
    lines += [f"G1 X{13 + 0.1 * k:.3f} Y{0.04 * rng.standard_normal():.3f}" for k in range(1, 220)] + ["M30"]
    return lines


@pytest.mark.parametrize("read", ["#5420", "#<_X>", "#<_hal[plasmac.cut-feed-rate]>", "# < _abs_y >"])
def test_smoothing_stops_where_a_system_parameter_is_read(tmp_path, read):
    """#5420 is the controller's current X, which the reader cannot know, as are LinuxCNC's read-only
    named parameters and HAL pins: from the window holding that line on, the program is kept as it is,
    and the report says why."""
    lines = [line.replace("#5420", read) for line in system_parameter_program()]
    program = tmp_path / "p.nc"
    program.write_text("\n".join(lines) + "\n")
    done = _run(program, "-o", "out.nc", "--report", "r.json", "--method", "mean", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    after = (tmp_path / "out.nc").read_text().splitlines()
    read_at = lines.index(f"#<x>={read} (where the controller stands)")
    assert after[:100] != lines[:100] and after[read_at - 30:] == lines[read_at - 30:]
    rows = json.loads((tmp_path / "r.json").read_text())["window_rows"]
    said = read.replace(" ", "").lower()
    kept = [r["status"].startswith(f"kept: {said} at line 133") for r in rows]
    assert kept[:2] == [False, False] and all(kept[2:]) and len(kept) > 3, rows[2]["status"]


def test_a_controller_parameter_is_named_where_the_reader_follows_the_program():
    with pytest.raises(GCodeError, match=r"p.nc:2: word X: #<_x> is the controller's state"):
        read_text("G21 G90\nG1 X[#<_x> + 1] F100\n", "p.nc")
    with pytest.raises(GCodeError, match="named parameter #<_mine> is read before it is set"):
        read_text("G21 G90\nG1 X[#<_mine> + 1] F100\n", "p.nc")  # a global of the program's, not the controller's


def test_the_stop_carries_over_to_every_later_part_of_a_long_program(tmp_path):
    from toolpath.smooth.command import DISPATCH, SMOOTHING, classifier
    from toolpath.smooth.rewrite import RewriteOptions
    from toolpath.smooth.stream import smooth_parts

    lines = system_parameter_program()
    program = tmp_path / "p.nc"
    program.write_text("\n".join(lines) + "\n")
    options = RewriteOptions(tolerance=0.01, smoothing=SMOOTHING, method="mean_filter", mapping=DISPATCH, seed=0)
    parts = list(smooth_parts(program, classifier("rule"), options, part_bytes=1500))
    assert len(parts) > 3
    statuses = [w.status for part in parts for w in part.result.windows]
    first_kept = next(k for k, s in enumerate(statuses) if s.startswith("kept: #5420"))
    assert all(s.startswith("kept: #5420") for s in statuses[first_kept:]) and first_kept == 2
    assert "".join(part.result.text for part in parts).splitlines()[lines.index("G1 X[#<x> + 0.1] Y0.02"):] == \
        lines[lines.index("G1 X[#<x> + 0.1] Y0.02"):]


def test_a_program_without_units_is_smoothed_only_in_the_units_it_is_given(tmp_path):
    """No G20 / G21: refused (exit 2, nothing written) until --units says which; inch reads it as a G20
    program does, and the report records what was assumed."""
    body = [line for line in rough_with_block_delete(200).splitlines() if not line.startswith(("/", "G21"))]
    program = tmp_path / "p.nc"
    program.write_text("\n".join(body) + "\n")
    done = _run(program, "-o", "out.nc", "--method", "mean", cwd=tmp_path)
    assert done.returncode == 2 and "--units mm or --units inch" in done.stderr
    assert not (tmp_path / "out.nc").exists()
    assert _run(program, "-o", "in.nc", "--units", "inch", "--report", "r.json", "--method", "mean",
                cwd=tmp_path).returncode == 0
    assert json.loads((tmp_path / "r.json").read_text())["units"] == {"set_by_program": None, "assumed": "inch"}
    stated = tmp_path / "g20.nc"
    stated.write_text("G20\n" + "\n".join(body) + "\n")
    assert _run(stated, "-o", "g20_out.nc", "--method", "mean", cwd=tmp_path).returncode == 0
    assert (tmp_path / "g20_out.nc").read_text() == "G20\n" + (tmp_path / "in.nc").read_text()
    assert _run(program, "-o", "mm.nc", "--units", "mm", "--method", "mean", cwd=tmp_path).returncode == 0
    assert (tmp_path / "mm.nc").read_text() != (tmp_path / "in.nc").read_text()  # 25.4x the tolerance apart


# --- the whole path, as an independent controller model reads it, at both block-delete states ----------

_WORD = re.compile(r"([A-Za-z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")


def controller_path(text: str, block_delete: bool) -> np.ndarray:
    """Every XY position the tool stands at, as a minimal RS-274 control reads ``text`` (G0 / G1, G20 / G21,
    G90 / G91, modal words, ``( )`` and ``;`` comments, N words, block delete with the switch on or off):
    written apart from the package's reader on purpose."""
    x = y = 0.0
    inch, absolute, path = False, True, [(0.0, 0.0)]
    for raw in text.splitlines():
        line = re.sub(r"\([^)]*\)|;.*", " ", raw).strip()
        if line.startswith("/"):
            if block_delete:
                continue
            line = line[1:]
        words = [(letter.upper(), float(number)) for letter, number in _WORD.findall(line)]
        codes = {v for letter, v in words if letter == "G"}
        inch = True if 20 in codes else False if 21 in codes else inch
        absolute = True if 90 in codes else False if 91 in codes else absolute
        scale = 25.4 if inch else 1.0
        moved = False
        for letter, value in words:
            if letter in "XY":
                moved = True
                if letter == "X":
                    x = value * scale if absolute else x + value * scale
                else:
                    y = value * scale if absolute else y + value * scale
        if moved:
            path.append((x, y))
    return np.array(path)


@st.composite
def controller_programs(draw) -> str:
    """A rough cut whose lines mix full and modal moves, block-deleted moves, N words, comments and unit
    switches (each number written in the units then in force)."""
    rng = np.random.default_rng(draw(st.integers(0, 10_000)))
    inch = draw(st.booleans())
    lines = [f"{'G20' if inch else 'G21'} G90 G17", "G0 X0 Y0", "G1 F300"]
    for k in range(1, draw(st.integers(60, 180))):
        x, y = 0.1 * k, 0.03 * rng.standard_normal()
        if draw(st.integers(0, 30)) == 0:
            inch = not inch
            lines.append("G20" if inch else "G21")
        unit, digits = (25.4, 5) if inch else (1.0, 3)
        kind = draw(st.sampled_from(["full", "full", "full", "modal", "x only", "deleted", "numbered", "comment"]))
        xs, ys = f"X{x / unit:.{digits}f}", f"Y{y / unit:.{digits}f}"
        lines.append({"full": f"G1 {xs} {ys}", "modal": f"{xs} {ys}", "x only": f"G1 {xs}",
                      "deleted": f"/G1 {xs} {ys}", "numbered": f"N{10 * k} G1 {xs} {ys}",
                      "comment": f"G1 {xs} {ys} (pass {k})"}[kind])
    return "\n".join(lines + ["M30"]) + "\n"


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(text=controller_programs())
def test_property_the_whole_path_holds_the_tolerance_at_both_switch_states(text):
    import tempfile
    from pathlib import Path

    from toolpath.smooth.command import main

    with tempfile.TemporaryDirectory() as folder:
        source = Path(folder) / "p.nc"
        source.write_text(text)
        assert main([str(source), "-o", str(Path(folder) / "out.nc"), "--method", "mean"]) == 0
        after = (Path(folder) / "out.nc").read_text()
    for switch in (False, True):
        before_path, after_path = controller_path(text, switch), controller_path(after, switch)
        assert len(before_path) == len(after_path)
        assert float(hausdorff(before_path, after_path)) <= 0.01 + 1e-9, f"block delete {'on' if switch else 'off'}"
