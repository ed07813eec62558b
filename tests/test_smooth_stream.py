"""``toolpath smooth`` in parts: the same windows and the same bytes as smoothing the program whole."""

from __future__ import annotations

import numpy as np
import pytest

from toolpath.gcode import GCodeError, read_file
from toolpath.gcode.reading import text_parts
from toolpath.smooth.command import DISPATCH, SMOOTHING, classifier
from toolpath.smooth.rewrite import RewriteOptions
from toolpath.smooth.stream import Combined, smooth_parts

OPTIONS = RewriteOptions(tolerance=0.01, smoothing=SMOOTHING, method="mean_filter", mapping=DISPATCH, seed=0)


def _program(points: int, seed: int = 0) -> str:
    rng = np.random.default_rng(seed)
    s = np.arange(points) * 0.2
    x = 40 * np.cos(s / 30) + rng.normal(0, 0.002, points)
    y = 40 * np.sin(s / 30) + np.where(rng.random(points) < 0.1, rng.normal(0, 0.1, points), 0)
    body = [f"N{k} G1 X{a:.3f} Y{b:.3f}" + (" (note)" if k % 97 == 0 else "")
            for k, (a, b) in enumerate(zip(x, y, strict=True))]
    lift = ["G0 Z5", "G0 X40 Y0", "G1 Z-1 F300"]  # a second run after a rapid
    return "\n".join(["G21 G90", "G0 X40 Y0", "G1 Z-1 F600", *body[:700], *lift, *body[700:], "G0 Z5", "M30"]) + "\n"


def _smooth(path, part_bytes):
    total, text = Combined(), []
    for part in smooth_parts(path, classifier("rule"), OPTIONS, part_bytes=part_bytes):
        text.append(part.result.text)
        total.add(part, (0.0, 0.0, None))
    return "".join(text), total


def test_parts_give_the_bytes_and_windows_of_the_whole(tmp_path):
    path = tmp_path / "in.nc"
    path.write_text(_program(1500))
    whole, one = _smooth(path, 1 << 30)
    parted, many = _smooth(path, 2000)  # ~60 lines a part: every run crosses many parts
    assert parted == whole
    assert [(w.first_line, w.last_line, w.category, w.status) for w in many.windows] == \
           [(w.first_line, w.last_line, w.category, w.status) for w in one.windows]
    assert np.array_equal(many.changed_lines, one.changed_lines) and len(one.changed_lines) > 0
    assert many.lines == one.lines == len(read_file(path).lines)
    assert many.parts > 10 and one.parts == 1 and many.restarts == one.restarts == []


def test_parameters_near_a_part_end_are_read_once_and_stay_within_tolerance(tmp_path):
    # '#1 = [#1 + 1]' must not run twice: lines that set parameters never wait for the next part
    lines = ["G21 G90", "#1 = 0", "G0 X0 Y0", "G1 Z-1 F300"]
    rng = np.random.default_rng(1)
    for k in range(400):
        lines.append(f"G1 X{k * 0.2:.3f} Y{rng.normal(0, 0.02):.3f}")
        if k % 30 == 0:
            lines.append("#1 = [#1 + 1]")
    lines += ["G1 X#1 Y0", "M30"]
    path = tmp_path / "params.nc"
    path.write_text("\n".join(lines) + "\n")
    parted, many = _smooth(path, 3000)  # ~130 lines a part, each end near a parameter line
    out = tmp_path / "out.nc"
    out.write_text(parted)
    before, after = read_file(path), read_file(out)
    assert after.points[-1, 0] == before.points[-1, 0] == 14.0  # #1 counted to 14, once each
    assert many.windows and max(w.deviation_mm for w in many.windows) <= 0.01
    assert many.restarts and not one_part_restarts(path)  # the restarts are counted, never silent


def one_part_restarts(path):
    return _smooth(path, 1 << 30)[1].restarts


def test_a_nurbs_block_across_a_part_end_is_read_once(tmp_path):
    lines = _program(600).splitlines()
    block = ["G0 X40 Y0", "G6.2 P3 K0 X40 Y0", "K0 X40 Y20", "K0 X20 Y20", "K1", "K1", "K1", "G1 X20 Y10"]
    path = tmp_path / "nurbs.nc"
    path.write_text("\n".join(lines[:300] + block + lines[300:]) + "\n")
    whole, one = _smooth(path, 1 << 30)
    parted, many = _smooth(path, 1500)
    out = tmp_path / "out.nc"
    out.write_text(parted)
    assert read_file(out).points.shape == read_file(path).points.shape
    assert many.lines == one.lines and max(w.deviation_mm for w in many.windows) <= 0.01


def test_every_corpus_program_smooths_to_the_same_bytes_in_parts(corpus):
    # parts of ~3 KB: every program is cut many times, next to arcs, parameters and Z moves
    for path in sorted(p for p in corpus.iterdir() if p.suffix != ".md"):
        whole, _ = _smooth(path, 1 << 30)
        parted, _ = _smooth(path, 3000)
        assert parted == whole, path.name


@pytest.mark.parametrize("data", [b"G1 X1\rG1 X2\rG1 X3\r\nG1 X4\r\n", b"G1 X1\r\nG1 X2\r\n", b"a\rb\nc"])
def test_text_parts_never_split_a_crlf_and_keep_every_byte(tmp_path, data):
    path = tmp_path / "cr.nc"
    path.write_bytes(data)
    for size in range(1, len(data) + 1):
        parts = list(text_parts(path, size))
        assert "".join(parts).encode() == data
        assert not any(a.endswith("\r") and b.startswith("\n") for a, b in zip(parts, parts[1:], strict=False))


def test_a_line_too_long_in_a_later_part_is_refused_with_its_line(tmp_path):
    path = tmp_path / "long.nc"
    path.write_bytes(b"G1 X1\n" * 3000 + b"X" * 20000 + b"\nG1 X2\n")
    with pytest.raises(GCodeError, match=r"long.nc:3001: the line is longer than"):
        list(text_parts(path, 4096))
