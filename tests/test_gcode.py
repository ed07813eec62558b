"""The G-code reader, writer and CLI: each dialect feature, each error, fuzz, round trip, corpus."""

import contextlib
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from toolpath.gcode import (
    GCodeError,
    Motion,
    Pass,
    ProgramSpec,
    ReaderOptions,
    read_file,
    read_text,
    replace_motion,
    write_program,
)
from toolpath.gcode.__main__ import main as cli_main


def xy(program):
    return program.points[:, :2]


# --- dialect features -------------------------------------------------------------------------

def test_linear_moves_kinds_and_source_lines():
    p = read_text("G21 G90\nG0 X1 Y1\nG1 X2 Y1 F100\nX2 Y3\n")
    assert xy(p).tolist() == [[1, 1], [2, 1], [2, 3]]
    assert p.kinds.tolist() == [Motion.RAPID, Motion.FEED, Motion.FEED]
    assert p.lines_of_points.tolist() == [2, 3, 4]
    assert p.units == "mm"


@pytest.mark.parametrize("code, mid_sign", [("G3", 1), ("G2", -1)])
def test_ij_arc_direction_and_chord_tolerance(code, mid_sign):
    tol = 0.001
    p = read_text(f"G0 X10 Y0\n{code} X-10 Y0 I-10 J0\n", options=ReaderOptions(chord_tolerance=tol))
    arc = xy(p)[1:]
    assert np.allclose(np.hypot(arc[:, 0], arc[:, 1]), 10.0)
    assert arc[-1].tolist() == [-10, 0]
    assert np.sign(arc[len(arc) // 2, 1]) == mid_sign  # G3 goes through +Y, G2 through -Y
    step = np.arccos(np.clip((arc[1:] * arc[:-1]).sum(1) / 100.0, -1, 1))
    assert np.all(10.0 * (1 - np.cos(step / 2)) <= tol + 1e-12)  # sagitta of every chord


def test_r_arc_minor_and_major():
    minor = xy(read_text("G0 X1 Y0\nG3 X0 Y1 R1\n"))[1:]
    assert np.allclose(np.hypot(*minor.T), 1.0)  # centre (0, 0): a quarter circle
    major = xy(read_text("G0 X1 Y0\nG3 X0 Y1 R-1\n"))[1:]
    assert np.allclose(np.hypot(major[:, 0] - 1, major[:, 1] - 1), 1.0)  # centre (1, 1): 270 deg
    assert major[:, 0].max() > 1.99 and major[:, 1].max() > 1.99  # through (2, 1) and (1, 2)


def test_full_circle_and_helix_and_turns():
    p = read_text("G0 X5 Y0 Z0\nG2 X5 Y0 Z-1 I-5 J0\n")
    arc = p.points[1:]
    assert arc[:, 0].min() == pytest.approx(-5, abs=1e-3)
    assert np.all(np.diff(arc[:, 2]) < 0) and arc[-1, 2] == -1  # Z falls linearly: a helix
    two = read_text("G0 X5 Y0\nG2 X5 Y0 I-5 J0 P2\n")
    assert len(two.points) - 1 == pytest.approx(2 * (len(arc)), abs=2)


def test_inch_units_are_converted_to_mm_and_incremental_mode():
    p = read_text("G20 G91\nG1 X1 Y0.5\nX1\n")
    assert np.allclose(xy(p), [[25.4, 12.7], [50.8, 12.7]])
    assert p.units == "inch"
    assert read_text("G1 X1\n").units == "mm (no unit word)"


def test_modal_arc_with_lowercase_r_word_before_axes():
    p = read_text("g20\ng0 x1 y0\ng2 r1 x0 y-1\nr1 x-1 y0\n")
    assert p.kinds.tolist()[-1] == Motion.ARC
    assert xy(p)[-1].tolist() == pytest.approx([-25.4, 0])


@pytest.mark.parametrize("initial, kind", [(0, Motion.RAPID), (1, Motion.FEED)])
def test_coordinates_before_any_g_word_use_the_initial_motion(initial, kind):
    p = read_text("X1 Y1\nX2 Y2\n", options=ReaderOptions(initial_motion=initial))
    assert p.kinds.tolist() == [kind, kind]


def test_compact_padded_lowercase_numbered_commented_words():
    text = "%\nN10 G01X1.5Y-2F300 (cut)\nn20 g1 x2 ; trailing\n\tG1\tX3 (a)(b) Y-2\n/G1 X9 Y9\n%\n"
    p = read_text(text)
    assert xy(p).tolist() == [[1.5, -2], [2, -2], [3, -2], [9, 9]]
    skipped = read_text(text, options=ReaderOptions(block_delete=True))
    assert xy(skipped).tolist()[-1] == [3, -2]


def test_crlf_and_other_words_are_kept_in_lines():
    text = "G21\r\nT1 M6\r\nS1000 M3\r\nG43 H1 D1\r\nG1 X1 F100\r\nM30\r\n"
    p = read_text(text)
    assert "".join(p.lines) == text
    assert p.lines[1] == "T1 M6\r\n"
    assert xy(p).tolist() == [[1, 0]]


def test_g92_offset_shifts_following_absolute_moves():
    p = read_text("G0 X10 Y10\nG92 X0 Y0\nG1 X1 Y0\nG92.1\nG1 X1 Y0\n")
    assert xy(p).tolist() == [[10, 10], [11, 10], [1, 0]]


@pytest.mark.parametrize("text, expected", [
    ("#1 = 2\nG1 X#1\n", 2.0),                                    # numbered
    ("G1 X#7\n", 0.0),                                            # unset numbered parameters are 0
    ("#<Depth Of Cut> = 1.5\nG1 X#<depthofcut>\n", 1.5),          # names ignore case and blanks
    ("#1=2\nG1 X[#1*2+1]\n", 5.0),                                # precedence: * before +
    ("G1 X[2**3*2]\n", 16.0),                                     # ** binds tightest
    ("G1 X[1+2 GT 2]\n", 1.0),                                    # comparison below arithmetic
    ("G1 X[-7 MOD 3]\n", 2.0),                                    # LinuxCNC's MOD is non-negative
    ("G1 X[SIN[30]*2]\n", 1.0),                                   # functions take degrees
    ("G1 X[ATAN[1]/[1]]\n", 45.0),
    ("G1 X[ROUND[-2.5]] Y[FIX[-2.5]] Z[FUP[2.1]]\n", -3.0),
    ("#2=3\n#1=2\nG1 X##1\n", 3.0),                               # indirect: #[#1]
    ("G1 X-#3\n", -0.0),
    ("#1=1\n#1=2 #2=#1\nG1 X#2\n", 1.0),                          # a line's values see the old parameters
    ("#<_g> = 4\nG1 X[EXISTS[#<_g>] + EXISTS[#<h>]]\n", 1.0),
])
def test_parameters_and_expressions_hand_cases(text, expected):
    assert read_text(text).points[-1, 0] == pytest.approx(expected)


def test_g28_and_g30_return_to_their_stored_positions_by_rapids():
    p = read_text("G21 G90\nG0 X5 Y5 Z5\nG30.1\nG1 X9 Y1 Z1\nG28 Z6\nG28\nG30\nG1 X2\n")
    assert p.points.tolist() == [[5, 5, 5], [9, 1, 1], [9, 1, 6], [9, 1, 0], [0, 0, 0], [5, 5, 5], [2, 5, 5]]
    assert p.kinds.tolist() == [0, 1, 0, 0, 0, 0, 1]  # G28 Z6: via Z6, then Z only to its home; G28: all axes
    assert p.points[-1].tolist() == [2, 5, 5]


def test_parameters_set_on_a_skipped_line_are_not_set():
    p = read_text("#1=5\n/#1=7\nG1 X#1\nM30\n#1=9\n", options=ReaderOptions(block_delete=True))
    assert p.points[-1, 0] == 5.0


def test_program_end_stops_interpretation():
    p = read_text("G1 X1\nM30\nG1 X5\n")
    assert xy(p).tolist() == [[1, 0]]


# --- errors -------------------------------------------------------------------------------------

@pytest.mark.parametrize("text, line, fragment", [
    ("G1 X1\nO100 sub\n", 2, "O-word"),
    ("#1 5\n", 1, "set with '='"),
    ("G1 X#<nothing>\n", 1, "read before it is set"),
    ("G1 X[1+2\n", 1, "never closed"),
    ("G1 X[1/0]\n", 1, "undefined"),
    ("G1 X[SQRT[-1]]\n", 1, "undefined"),
    ("#0 = 1\n", 1, "not an integer in 1-5602"),
    ("G1 X1 [2]\n", 1, "must follow a word letter"),
    ("G6.2 X1\n", 1, "NURBS"),
    ("G5.2 X1\n", 1, "not closed by G5.3"),
    ("G5 X1 I1 J1 P1 Q1\n", 1, "only G5.2 / G5.3"),
    ("G18\n", 1, "XY plane"),
    ("G19\n", 1, "XY plane"),
    ("G41 D1\n", 1, "cutter compensation"),
    ("G81 X1 Y1 Z-1 R1\n", 1, "canned cycle"),
    ("G1 X1 (open\n", 1, "never closed"),
    ("G0 G1 X1\n", 1, "two motion"),
    ("G1 X\n", 1, "has no number"),
    ("G1 X1 A5\n", 1, "axis word A"),
    ("G1 X1 &\n", 1, "unexpected character"),
    ("G1 X1 $\n", 1, "word $ has no number"),  # LinuxCNC's spindle select: $0, $1
    ("G1 X1 X2\n", 1, "appears twice"),
    ("G0 X1\nG2 X2 Y0\n", 2, "needs I/J or R"),
    ("G0 X0\nG2 X10 Y0 I1 J0\n", 2, "radius to the end of the arc differs"),
    ("G0 X0\nG2 X10 Y0 R1\n", 2, "shorter than half the chord"),
    ("G0 X1\nG3 X1 R1\n", 2, "same point"),
    ("M98 P100\n", 1, "M98"),
    ("G7\n", 1, "G7 is not supported"),
    ("G80\nX1\n", 2, "no motion mode"),
])
def test_unsupported_or_malformed_input_names_the_line(text, line, fragment):
    with pytest.raises(GCodeError) as err:
        read_text(text, source="part.nc")
    assert err.value.line == line
    assert fragment in err.value.message
    assert str(err.value).startswith(f"part.nc:{line}: ")


def test_missing_file_is_a_gcode_error(tmp_path):
    with pytest.raises(GCodeError, match=":0: cannot read file"):
        read_file(tmp_path / "nope.nc")


_TOKENS = st.sampled_from(["G0", "G1", "G2", "G3", "G01", "g91", "G90", "G20", "G21", "X1.5", "Y-2",
                           "Z.5", "I1", "J-1", "R2", "F100", "M3", "(c)", ";x", "N5", "#1", "O1", "/",
                           "%", "G17", "G92", "X", "G18", "\t", "r-1", "x0", "y0", "P2", "G80"])


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=80))
def test_fuzz_random_text_raises_only_gcode_error(text):
    with contextlib.suppress(GCodeError):
        read_text(text)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.lists(_TOKENS, max_size=6).map(" ".join), max_size=8).map("\n".join))
def test_fuzz_random_token_programs_raise_only_gcode_error(text):
    try:
        program = read_text(text)
    except GCodeError:
        return
    assert np.all(np.isfinite(program.points))


# --- writer -------------------------------------------------------------------------------------

def square_passes():
    sq = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], dtype=float)
    return [Pass(sq, -1.0), Pass(sq * 1.123456 + 0.5, -1.0)]


def test_write_then_read_round_trip():
    passes = square_passes()
    p = read_text(write_program(passes, ProgramSpec(decimals=3)))
    feed = p.points[p.kinds == Motion.FEED]
    # each pass: the plunge (at the pass's first XY), then its remaining points, rounded to 3 decimals
    assert np.array_equal(feed[:, :2], np.concatenate([np.round(q.xy, 3) for q in passes]))
    assert set(feed[:, 2]) == {-1.0}


def test_stay_down_links_passes_with_a_feed_move():
    text = write_program(square_passes(), ProgramSpec(stay_down=True))
    p = read_text(text)
    assert (p.kinds == Motion.RAPID).sum() == 3  # retract, rapid to the first pass, final retract


def test_replace_motion_keeps_every_other_line_byte_for_byte():
    text = "(hdr)\r\nG21 G90\r\nG0 X0 Y0\r\nG1 X1 Y0 F100\r\nX2 Y0\r\nX3 Y0\r\nM5\r\nG1 X4 Y0\r\n"
    p = read_text(text, "a.nc")
    new = np.array([[1.5, 0.2], [2.5, 0.2], [3.0, 0.0]])
    out = replace_motion(p, [(5, 6, new)])
    old_lines, new_lines = text.split("\r\n"), out.split("\r\n")
    assert new_lines[:4] == old_lines[:4] and new_lines[-3:] == old_lines[-3:]
    q = read_text(out)
    assert np.allclose(xy(q)[-4:], [[1.5, 0.2], [2.5, 0.2], [3, 0], [4, 0]])


def test_replace_motion_in_incremental_inch_program_keeps_later_moves():
    text = "G20 G91\nG1 X0.1 Y0\nX0.1 Y0\nX0.1 Y0\nX0.1 Y0.1\n"
    p = read_text(text)
    end = p.states[4].position[:2]  # where line 4 leaves the tool
    out = replace_motion(p, [(3, 4, np.array([[5.0, 0.3], end]))])
    q = read_text(out)
    assert np.allclose(xy(q)[-1], xy(p)[-1])
    assert np.allclose(xy(q)[1], [5.0, 0.3], atol=0.0013)  # written in inch with 4 decimals
    assert "X0.1 Y0.1" in out.splitlines()[-1]


@pytest.mark.parametrize("text, rng, fragment", [
    ("G1 X1\nX2 (keep me)\nX3\n", (2, 2), "comment"),
    ("G1 X1\nX2 M8\nX3\n", (2, 2), "M8"),
    ("G0 X1\nG0 X2\nX3\n", (2, 2), "G0"),
    ("G0 X1 Y0\nG2 X0 Y-1 R1\nX-1 Y0 R1\n", (2, 2), "relies on modal G2"),
])
def test_replace_motion_refuses_to_lose_anything(text, rng, fragment):
    p = read_text(text, "b.nc")
    end = p.states[rng[1]].position
    with pytest.raises(GCodeError, match=fragment):
        replace_motion(p, [(rng[0], rng[1], np.array([end[:2]]))])


def test_replace_motion_must_end_where_the_range_ended():
    p = read_text("G1 X1\nX2\nX3\n")
    with pytest.raises(ValueError, match="original end"):
        replace_motion(p, [(2, 2, np.array([[2.5, 0.0]]))])


# --- real programs and CLI ----------------------------------------------------------------------

def test_every_corpus_file_reads_or_fails_with_a_listed_feature(corpus):
    files = sorted(f for f in corpus.iterdir() if f.suffix in {".nc", ".ngc", ".gcode", ".tap"})
    assert len(files) == 12
    read = 0
    for f in files:
        try:
            p = read_file(f)
        except GCodeError as exc:
            raise AssertionError(f"{f.name} should read: {exc}") from None
        read += 1
        assert len(p.points) > 50 and np.all(np.isfinite(p.points))
    assert read == 12


def test_cli_summarises_files_and_fails_on_malformed(corpus, tmp_path, capsys):
    assert cli_main([str(corpus / "ugs_square_g91.nc")]) == 0
    out = capsys.readouterr().out
    assert "102 points" in out and "units mm" in out and "X[0.000, 1000.000]" in out
    bad = tmp_path / "bad.nc"
    bad.write_text("G21\nG1 X1\nG1 X#<depth>\n")
    assert cli_main([str(bad)]) == 1
    assert capsys.readouterr().err.strip() == f"{bad}:3: word X: named parameter #<depth> is read before it is set"


def test_arc_points_follow_the_r_arcs_of_a_real_file(corpus):
    p = read_file(corpus / "linuxcnc_arcspiral.ngc")
    arc = p.points[p.kinds == Motion.ARC]
    r = np.hypot(arc[:, 0], arc[:, 1])
    assert r.max() == pytest.approx(2.0 * 25.4, rel=0.01)  # spiral radius shrinks from 2 inch
    assert math.isclose(p.points[:, 2].min(), -0.1 * 25.4)
