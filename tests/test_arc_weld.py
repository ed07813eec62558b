"""`toolpath smooth --arcs`: runs of G1 lines become one G2/G3 only where the arc lies within the two-sided
tolerance of the original path; every other line stays byte for byte; the next G1 keeps its meaning."""

import json
import math
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from conftest import REPO
from toolpath.gcode import ReaderOptions, read_text
from toolpath.geometry.hausdorff import hausdorff, pieced_hausdorff
from toolpath.geometry.labels.windows import feed_runs
from toolpath.smooth.arc_weld import COMPILED_POINTS, fit_arc, weld_arcs

CORPUS = REPO.parent / "shared" / "gcode-corpus"


def polygon_program(segments: int, radius: float = 10.0, units: str = "G21", decimals: int = 3,
                    tail: str = "X-5 Y-5") -> str:
    """A lead-in, a half circle as ``segments`` G1 lines (N and F words on the first), a modal G1 turning
    away (no arc, however flat, continues the circle into it), the end."""
    t = np.linspace(0.0, math.pi, segments + 1)
    pts = np.column_stack([radius * np.cos(t), radius * np.sin(t)])
    lines = [f"{units} G90 G17", f"G0 X{pts[0, 0] + radius / 20:.{decimals}f} Y0", "(contour)",
             f"G1 X{pts[0, 0]:.{decimals}f} Y0 F300",
             f"N10 G1 X{pts[1, 0]:.{decimals}f} Y{pts[1, 1]:.{decimals}f} F800"]
    lines += [f"G1 X{x:.{decimals}f} Y{y:.{decimals}f}" for x, y in pts[2:]]
    lines += [tail, "G0 Z5", "M30"]
    return "\n".join(lines) + "\n"


def _deviation(before: str, after: str, chord: float = 1e-4) -> float:
    """The two-sided distance of the paths with the arcs read as chords within ``chord`` mm of them, less
    that chord (the reader's default 1e-3 mm would add its own chord error to the arcs the controller
    runs): the figure is within twice the chord of the distance to the arcs themselves."""
    fine = ReaderOptions(chord_tolerance=chord)
    a, b = feed_runs(read_text(before, options=fine)), feed_runs(read_text(after, options=fine))
    assert len(a) == len(b)
    return max(pieced_hausdorff(p[0], q[0]) for p, q in zip(a, b, strict=True)) - chord


# --- the fit, by hand ---------------------------------------------------------------------------

def test_fit_arc_recovers_a_circle_and_its_direction():
    t = np.radians([10.0, 30.0, 50.0, 70.0])
    ccw = np.column_stack([3.0 + 5.0 * np.cos(t), -2.0 + 5.0 * np.sin(t)])
    arc = fit_arc(ccw)
    np.testing.assert_allclose(arc.centre, [3.0, -2.0], atol=1e-9)
    assert arc.radius == pytest.approx(5.0) and arc.sweep == pytest.approx(math.radians(60.0))
    assert fit_arc(ccw[::-1]).sweep == pytest.approx(-math.radians(60.0))  # clockwise


@pytest.mark.parametrize("points", [
    [[0, 0], [1, 0], [2, 0], [3, 0]],          # a straight line
    [[0, 0], [1, 1], [2, 0], [3, 1]],          # a zigzag turns both ways
    [[0, 0], [1e5, 1], [2e5, 0]],              # flatter than MAX_RADIUS
])
def test_fit_arc_refuses_what_is_not_one_arc(points):
    assert fit_arc(np.array(points, float)) is None


# --- whole programs ---------------------------------------------------------------------------

def test_a_fine_polygon_becomes_one_arc_and_nothing_else_changes():
    text = polygon_program(180)
    program = read_text(text)
    out, arcs, changed, note, _ = weld_arcs(program, program, 0.01)
    assert note is None and len(arcs) == 1 and arcs[0].lines_replaced >= 170 and not arcs[0].clockwise
    old, new = text.splitlines(), out.splitlines()
    arc_line = new[arcs[0].first_line - 1]
    assert arc_line.startswith("N10 G3 X") and " I" in arc_line and arc_line.endswith("F800")  # N and F kept
    # lines before the arc and after the replaced range are the same bytes; the modal G1 is made explicit
    assert new[:arcs[0].first_line - 1] == old[:arcs[0].first_line - 1]
    assert new[arcs[0].first_line] == "G1 " + old[arcs[0].last_line]
    assert new[arcs[0].first_line + 1:] == old[arcs[0].last_line + 1:]
    assert set(changed) == set(range(arcs[0].first_line, arcs[0].last_line + 2))
    assert arcs[0].deviation_mm <= 0.01 and _deviation(text, out) <= 0.01 + 1e-9
    assert read_text(out).points[-1].tolist() == program.points[-1].tolist()


def test_an_arc_the_input_already_has_is_kept_beside_the_ones_welded():
    # the reader's default chords (1e-3 mm) differ from the re-read check's: the input's own G3 must still
    # read as unmoved (tinyg_batman.tap was refused for it: "welding arcs moved a point it does not own")
    text = polygon_program(180, tail="G3 X-5 Y-5 I5 J0\nG1 X0 Y-5")
    program = read_text(text)
    assert ReaderOptions().chord_tolerance > 1e-4
    out, arcs, _, _, _ = weld_arcs(program, program, 0.01)
    assert len(arcs) == 1 and "G3 X-5 Y-5 I5 J0" in out.splitlines()
    assert _deviation(text, out) <= 0.01 + 1e-9


def test_a_coarse_polygon_keeps_its_lines():
    """30 chords on R10 sag 0.0137 mm: no arc through their ends comes within 0.01 mm of them."""
    text = polygon_program(30)
    program = read_text(text)
    out, arcs, changed, _, _ = weld_arcs(program, program, 0.01)
    assert arcs == [] and len(changed) == 0 and out == text


def test_the_whole_band_is_used():
    """36 chords on R10 sag 0.0095 mm: the arc through their vertices is 0.0095 mm from the chords' middles,
    within 0.01 mm, so the half circle is one arc (issue 44: the budget is no longer cut by a share for
    rounding and chords; the arc is measured as written), and it truly lies within the tolerance."""
    text = polygon_program(36)
    program = read_text(text)
    out, arcs, _, _, _ = weld_arcs(program, program, 0.01)
    assert len(arcs) == 1 and arcs[0].lines_replaced == 36
    assert 0.0095 <= _deviation(text, out, chord=1e-5) <= 0.01


def test_inch_programs_get_inch_numbers():
    text = polygon_program(180, radius=0.5, units="G20", decimals=4, tail="X-0.3 Y-0.2")
    program = read_text(text)
    out, arcs, _, _, _ = weld_arcs(program, program, 0.01)
    assert len(arcs) == 1
    arc_line = out.splitlines()[arcs[0].first_line - 1]
    assert " X-0.5000 Y0.0000 I" in arc_line  # program units, the line's four decimals
    assert _deviation(text, out) <= 0.01 + 1e-9


def test_absolute_arc_centres_are_left_alone():
    text = polygon_program(180).replace("G21 G90 G17", "G21 G90 G90.1 G17")
    program = read_text(text)
    out, arcs, _, note, _ = weld_arcs(program, program, 0.01)
    assert out == text and arcs == [] and "G90.1" in note


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(segments=st.integers(20, 400), radius=st.floats(1.0, 200.0), tolerance=st.sampled_from([0.002, 0.01, 0.05]),
       noise=st.floats(0.0, 0.01), seed=st.integers(0, 1000))
def test_property_arcs_stay_within_the_tolerance_and_the_program_keeps_its_end(segments, radius, tolerance, noise,
                                                                             seed):
    t = np.linspace(0.0, 1.5 * math.pi, segments + 1)
    rng = np.random.default_rng(seed)
    pts = np.column_stack([radius * np.cos(t), radius * np.sin(t)]) + noise * rng.standard_normal((segments + 1, 2))
    lines = ["G21 G90", f"G0 X{pts[0, 0]:.4f} Y{pts[0, 1]:.4f}"]
    lines += [f"G1 X{x:.4f} Y{y:.4f} F500" if k == 0 else f"X{x:.4f} Y{y:.4f}" for k, (x, y) in enumerate(pts[1:])]
    text = "\n".join([*lines, "M30"]) + "\n"
    program = read_text(text)
    out, arcs, _, _, _ = weld_arcs(program, program, tolerance)
    assert _deviation(text, out) <= tolerance + 1e-9
    np.testing.assert_array_equal(read_text(out).points[-1], program.points[-1])
    assert all(a.deviation_mm <= tolerance for a in arcs)


@pytest.mark.skipif(not CORPUS.is_dir(), reason="../shared/gcode-corpus is absent (real CAM programs)")
@pytest.mark.parametrize("name", ["camotics_tiny_cat_outline.ngc", "tinyg_hacdc.gcode"])
def test_corpus_programs_get_arcs_within_tolerance(name, tmp_path):
    from toolpath.smooth.command import main

    source = CORPUS / name
    assert main([str(source), "-o", str(tmp_path / name), "--arcs", "--units", "mm",
                 "--report", str(tmp_path / "r.json")]) == 0
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["arcs"]["fitted"] > 10 and report["largest_deviation_mm"] <= 0.01
    text = source.read_bytes().decode("utf-8", errors="surrogateescape")
    after = (tmp_path / name).read_bytes().decode("utf-8", errors="surrogateescape")
    # the whole program at the reader's own chords (finer ones make its arcs too many points to compare
    # whole), the chords' own error taken off; each arc's exact figure is the report's, above
    assert _deviation(text, after, chord=1e-3) <= 0.01 + 1e-9


# --- what a controller reads: block delete, comments, N words (issue 42) ----------------------------

def _weld_text(text: str, tolerance: float = 0.01) -> str:
    program = read_text(text)
    welded, records, _, _, _ = weld_arcs(program, program, tolerance)
    assert records, "the test program must weld at least one arc"
    return welded


@pytest.mark.parametrize("switch", [False, True])
def test_a_block_deleted_line_and_a_commented_line_are_kept_and_the_path_holds_at_both_switch_states(switch):
    from toolpath.gcode import ReaderOptions

    lines = polygon_program(60).splitlines()
    lines[20] = "/" + lines[20]                    # runs only with the block-delete switch off
    lines[40] = lines[40] + " (MSG, pass 3)"      # an operator message on a move
    text = "\n".join(lines) + "\n"
    welded = _weld_text(text)
    assert lines[20] + "\n" in welded and lines[40] + "\n" in welded
    options = ReaderOptions(block_delete=switch)
    before = feed_runs(read_text(text, options=options))
    after = feed_runs(read_text(welded, options=options))
    assert max(float(hausdorff(p[0], q[0])) for p, q in zip(before, after, strict=True)) <= 0.01 + 1e-9


def test_the_explicit_g1_after_an_arc_comes_after_the_lines_n_word():
    pts = [(10 * math.cos(a), 10 * math.sin(a)) for a in np.linspace(0.0, math.pi, 81)]
    lines = ["G21 G90 G17", f"G0 X{pts[0][0]:.3f} Y0", f"N1 G1 X{pts[0][0]:.3f} Y0 F300"]
    lines += [f"N{k + 1} X{x:.3f} Y{y:.3f}" for k, (x, y) in enumerate(pts[1:], start=1)] + ["N99 M30"]
    welded = _weld_text("\n".join(lines) + "\n")
    for line in welded.splitlines():
        words = line.split()
        assert all(not w.upper().startswith("N") for w in words[1:]), f"an N word in mid-line: {line!r}"
    assert any(re.fullmatch(r"N\d+ G1 X\S+ Y\S+", line) for line in welded.splitlines())


def _long_arcs(chain, end, *_):
    out = []
    for i in range(0, end - 2, 20):
        q = min(i + 20, end)
        arc = fit_arc(chain.xy[i:q + 1])
        if arc is not None:
            out.append((i, q, arc.centre))
    return out


def test_an_arc_the_exact_check_rejects_is_kept_as_its_lines(monkeypatch):
    """With the cheap bound switched off every candidate arc is written; the exact re-read check then
    rejects those farther than the tolerance, and each is kept as its G1 lines, never the whole program
    refused (issue 44)."""
    import toolpath.smooth.arc_weld as arc_weld

    rng = np.random.default_rng(3)
    t = np.linspace(0.0, math.pi, 121)
    radius = 10.0 + rng.normal(0.0, 0.02, t.size)  # a wavy half circle: long arcs overshoot the band
    lines = ["G21 G90 G17", "G0 X10.2 Y0", "G1 X10.000 Y0 F300"]
    lines += [f"G1 X{r * math.cos(a):.3f} Y{r * math.sin(a):.3f}" for r, a in zip(radius[1:], t[1:], strict=True)]
    text = "\n".join(lines + ["G1 X-10 Y-5", "M30"]) + "\n"
    program = read_text(text)
    monkeypatch.setattr(arc_weld, "fewest_blocks", _long_arcs)  # the screen switched off: arcs of 20 chords
    monkeypatch.setattr(arc_weld, "_within", lambda program, xy, lines, original, i, q, tolerance, arc: (arc, 0.0))
    out, arcs, _, _, kept_as_lines = weld_arcs(program, program, 0.01)
    assert kept_as_lines > 0
    assert all(a.deviation_mm <= 0.01 + 1e-9 for a in arcs)
    assert _deviation(text, out) <= 0.01 + 1e-9


def test_arcs_alone_with_method_none(tmp_path):
    """`--method none --arcs` does ArcWelder's job alone: arcs, nothing smoothed; without --arcs the
    program comes back byte for byte (issue 44)."""
    from toolpath.smooth.command import main

    source = tmp_path / "p.nc"
    rng = np.random.default_rng(5)
    text = polygon_program(180)
    noisy = [line if not line.startswith("G1 X") or k < 6 else
             re.sub(r"Y(-?[\d.]+)", lambda m: f"Y{float(m.group(1)) + rng.normal(0, 0.002):.3f}", line)
             for k, line in enumerate(text.splitlines())]
    source.write_text("\n".join(noisy) + "\n")
    assert main([str(source), "-o", str(tmp_path / "same.nc"), "--method", "none"]) == 0
    assert (tmp_path / "same.nc").read_bytes() == source.read_bytes()
    assert main([str(source), "-o", str(tmp_path / "arcs.nc"), "--method", "none", "--arcs",
                 "--report", str(tmp_path / "r.json")]) == 0
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["arcs"]["fitted"] >= 1 and report["windows"]["total"] == 0
    out = (tmp_path / "arcs.nc").read_text()
    assert len(out.splitlines()) < len(noisy) and _deviation(source.read_text(), out) <= 0.01 + 1e-9


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), noise=st.floats(0.0, 0.05), sweep=st.floats(0.2, 3.0), n=st.integers(4, 40),
       shift=st.floats(0.0, 0.002))
@example(seed=0, noise=0.0, sweep=0.21875, n=20, shift=0.001953125)  # the end moved past the last vertex's ray
def test_the_spiral_bound_holds_the_exact_distance(seed, noise, sweep, n, shift):
    """Eq.-free geometry, checked by hand's equivalent: the exact two-sided distance between the polyline
    and the arc a reader runs from a centre and an end moved by rounding (a spiral between two radii;
    sampled at 1e-5 mm, so within that of it) never exceeds the spiral bound; with nothing moved the bound
    is the exact largest radial gap (a circle through the vertices: the largest sagitta)."""
    from toolpath.gcode.arcs import discretise_arc
    from toolpath.smooth.arc_weld import spiral_bound

    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, sweep, n))
    t[0], t[-1] = 0.0, sweep
    r = 5.0 + rng.normal(0.0, noise, n)
    r[0] = r[-1] = 5.0
    points = np.column_stack([r * np.cos(t), r * np.sin(t)])
    centre = rng.uniform(-shift, shift, 2)
    end = points[-1] + rng.uniform(-shift, shift, 2)
    bound = spiral_bound(points, points[0], end, centre, clockwise=False)
    if not math.isfinite(bound):
        return
    chords = discretise_arc(np.append(points[0], 0.0), np.append(end, 0.0), centre, False, 1e-5)[:, :2]
    exact = float(hausdorff(points, np.vstack([points[:1], chords])))
    assert exact <= bound + 2e-5
    if noise == 0.0 and shift == 0.0:
        half = np.hypot(*np.diff(points, axis=0).T) / 2.0
        assert bound == pytest.approx(float((5.0 - np.sqrt(25.0 - half ** 2)).max()), abs=1e-9)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), noise=st.floats(0.0, 0.02), decimals=st.integers(2, 5))
def test_the_screen_measures_each_arc_as_the_scalar_bound_does(seed, noise, decimals):
    """The vectorised screen (arc_search) gives, for every start and end it measures, the bound of
    spiral_bound on the same centre rounded as written: the two implementations agree."""
    from toolpath.smooth.arc_search import Chain, _bound
    from toolpath.smooth.arc_weld import spiral_bound

    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.02, 0.15, 12))
    xy = np.round(np.column_stack([8.0 * np.cos(t), 8.0 * np.sin(t)]) + rng.normal(0.0, noise, (12, 2)), decimals)
    chain = Chain(xy, xy, xy, np.ones(12), np.full(12, decimals), np.ones(12))
    starts, size = np.array([0, 2]), 8
    index = starts[:, None] + np.arange(size + 1)[None, :]
    p = xy[index] - xy[starts][:, None, :]
    centre = np.array([[-xy[s] * 1.001 for _ in range(size)] for s in starts])  # near the origin, local
    b, k = np.divmod(np.arange(len(starts) * size), size)  # every start with every end, as candidates
    vector = _bound(chain, starts, index, p, p, b, centre[b, k], k + 1).reshape(len(starts), size)
    for b, s in enumerate(starts):
        for j in range(1, size + 1):
            written = xy[s] + np.round(centre[b, j - 1] * 10.0 ** decimals) / 10.0 ** decimals
            scalar = spiral_bound(xy[s:s + j + 1], xy[s], xy[s + j], written, clockwise=False)
            both_inf = math.isinf(scalar) and math.isinf(vector[b, j - 1])
            assert both_inf or vector[b, j - 1] == pytest.approx(scalar, abs=1e-9)


def _plain_fewest_blocks(arc_search, chain, n, longest, budget):
    """The plain dynamic programme: every start measured at every end (a long window, no edge rule)."""
    blocks, came = np.arange(n), np.full(n, -1)
    for i in range(n - 2):
        if i and blocks[i - 1] + 1 < blocks[i]:
            blocks[i], came[i] = blocks[i - 1] + 1, -1
        j = np.arange(1, min(longest, n - 1 - i) + 1)[None, :]
        fits, _ = arc_search._measure_ends(chain, np.array([i]), j, np.ones_like(j, bool), n - 1, budget, 2, 1e4)
        for q in np.flatnonzero(fits[0]) + 1 + i:
            if blocks[i] + 1 < blocks[q]:
                blocks[q], came[q] = blocks[i] + 1, i
    plain, k = [], n - 1
    while k > 0:
        if came[k] < 0:
            k -= 1
        else:
            plain.append((int(came[k]), k))
            k = int(came[k])
    return plain[::-1]


def _turning_chain(arc_search, seed):
    rng = np.random.default_rng(seed)
    turn = np.concatenate([rng.uniform(0.01, 0.05, 70), np.zeros(20), rng.uniform(-0.08, -0.02, 60)])
    heading = np.cumsum(turn)
    xy = np.round(np.cumsum(np.column_stack([np.cos(heading), np.sin(heading)]) * 0.3, axis=0)
                  + rng.normal(0.0, 0.002, (len(turn), 2)), 3)
    return arc_search.Chain(xy, xy, xy, np.ones(len(xy)), np.full(len(xy), 3), np.ones(len(xy)))


@pytest.mark.parametrize("seed", [0, 1])
def test_the_search_skips_only_ends_it_cannot_improve(seed, monkeypatch):
    """With every start measured (no skipped starts) and windows longer than the longest arc, fewest_blocks
    measures a start only at the ends whose count it could lower: it chooses the very arcs of the plain
    dynamic programme that measures every start at every end."""
    from toolpath.smooth import arc_search

    monkeypatch.setattr(arc_search, "FIRST_WINDOW", 64)  # one window of the longest arcs: no edge rule
    monkeypatch.setattr(arc_search, "SKIP_GAP", 10 ** 6)
    chain = _turning_chain(arc_search, seed)
    n, longest, budget = len(chain.xy), 40, 0.01
    chosen = [(i, q) for i, q, _ in arc_search.fewest_blocks(chain, n - 1, budget, 2, longest, 1e4, 8)]
    assert len(chosen) >= 3
    assert chosen == _plain_fewest_blocks(arc_search, chain, n, longest, budget)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_measuring_only_the_last_starts_of_a_long_arc_writes_as_few_blocks(seed):
    """The search as it runs (windows that grow, only the last starts inside a long arc measured) leaves
    as few blocks as the plain dynamic programme on a path of two arcs and a straight run in noise."""
    from toolpath.smooth import arc_search

    chain = _turning_chain(arc_search, seed)
    n, longest, budget = len(chain.xy), 40, 0.01
    chosen = arc_search.fewest_blocks(chain, n - 1, budget, 2, longest, 1e4, 8)
    plain = _plain_fewest_blocks(arc_search, chain, n, longest, budget)

    def blocks(arcs):
        return len(arcs) + (n - 1) - sum(q - i for i, q, *_ in arcs)

    assert blocks(chosen) == blocks(plain) < n - 1 - 50


def test_a_straight_edge_in_noisy_steps_with_a_repeated_corner_becomes_one_arc():
    """A PCB edge as tinyg_hacdc.gcode cuts it: nine steps straight within 0.1 um of noise (no stable
    algebraic centre), the corner repeated by a move to where the tool stands.  The flattest arc allowed
    lies within the band; the repeated corner is passed over and takes a written G1."""
    edge = ["X3.4000Y8.9431", "X3.4055Y8.9268", "X3.4109Y8.9105", "X3.4163Y8.8941", "X3.4216Y8.8777",
            "X3.4270Y8.8612", "X3.4323Y8.8448", "X3.4377Y8.8284", "X3.4431Y8.8121", "X3.4486Y8.7958"]
    text = "\n".join(["G21 G90", "G0 X3.4000Y8.9431", "G1 Z-0.005 F100", *edge, "X3.4486Y8.7958",
                      "G0 Z1", "M30"]) + "\n"
    program = read_text(text)
    out, arcs, _, _, _ = weld_arcs(program, program, 0.01)
    assert len(arcs) == 1 and arcs[0].radius_mm > 1000.0
    lines = out.splitlines()
    assert lines[4].startswith("G2 X3.4486 Y8.7958 ") and lines[5] == "G1 X3.4486Y8.7958"
    assert lines[:4] == text.splitlines()[:4] and lines[6:] == ["G0 Z1", "M30"]
    assert _deviation(text, out, chord=1e-5) <= 0.01


@pytest.mark.parametrize(("repeat", "arcs"), [("F800", 1), ("F900", 2), ("F800 G93", 0)])
def test_an_f_word_repeating_the_feed_in_effect_does_not_break_an_arc(repeat, arcs):
    """A CAM post's F every few hundred lines at the feed already in effect changes nothing a controller
    does, so an arc passes over it; a new feed splits the arcs (each keeps its own); in inverse time
    (G93) an F is each move's own time, so no arc replaces such lines at all."""
    lines = polygon_program(60).splitlines()
    feed, *mode = repeat.split()
    if mode:  # every move its own F, as inverse time requires
        lines[0] += " G93"
        lines[5:] = [line + f" {feed}" if line.startswith("G1") else line for line in lines[5:]]
    else:
        lines[34] += f" {feed}"  # the half circle's 30th point
    text = "\n".join(lines) + "\n"
    program = read_text(text)
    out, records, _, _, _ = weld_arcs(program, program, 0.01)
    assert len(records) == arcs
    if arcs == 2:  # the new feed stays on the first line of the arc it starts
        assert any(line.startswith("G") and line.endswith(" F900") for line in out.splitlines())
        assert records[0].last_line == 34
    if arcs:
        assert _deviation(text, out) <= 0.01


def test_an_arc_over_a_change_of_feed_is_kept_as_its_lines(monkeypatch):
    """The re-read check compares the feed too: were the search to join lines across a new F (here it is
    made blind to F words), the arc that would run the second feed's lines at the first is kept as its
    lines, and every move of the output runs at the feed it had."""
    from toolpath.smooth import arc_runs

    lines = polygon_program(60).splitlines()
    lines[34] += " F900"
    text = "\n".join(lines) + "\n"
    program = read_text(text)
    monkeypatch.setattr(arc_runs, "has_feed", lambda *_: False)
    out, records, _, _, kept_as_lines = weld_arcs(program, program, 0.01)
    assert kept_as_lines >= 1
    assert all(r.last_line < 35 or r.first_line >= 35 for r in records)
    before, after = read_text(text), read_text(out)
    assert " F900" in out
    np.testing.assert_array_equal(np.unique(after.states.feed[after.lines_of_points]),
                                  np.unique(before.states.feed[before.lines_of_points]))


@pytest.mark.parametrize("seed", [0, 1])
def test_probing_the_last_ends_of_long_windows_writes_as_few_blocks(seed, monkeypatch):
    """From windows of GALLOP ends on, a start measures a window's last ends first and takes the others to
    fit when an arc fits there: on 1,200 noisy points of three long arcs (the longest 500 segments) that
    leaves the very arcs of measuring every end."""
    from toolpath.smooth import arc_search

    rng = np.random.default_rng(seed)
    turn = np.concatenate([np.full(500, 0.004), np.full(400, -0.006), np.full(300, 0.003)])
    heading = np.cumsum(turn)
    xy = np.round(np.cumsum(np.column_stack([np.cos(heading), np.sin(heading)]) * 0.2, axis=0)
                  + rng.normal(0.0, 0.001, (len(turn), 2)), 3)
    n = len(xy)
    chain = arc_search.Chain(xy, xy, xy, np.ones(n), np.full(n, 3), np.ones(n))

    def blocks(arcs):
        return len(arcs) + (n - 1) - sum(q - i for i, q, *_ in arcs)

    probed = arc_search.fewest_blocks(chain, n - 1, 0.01, 2, 500, 1e4, 8)
    monkeypatch.setattr(arc_search, "GALLOP", 10 ** 6)
    measured = arc_search.fewest_blocks(chain, n - 1, 0.01, 2, 500, 1e4, 8)
    assert blocks(probed) == blocks(measured) <= 8
    assert [(i, q) for i, q, _ in probed] == [(i, q) for i, q, _ in measured]


def test_a_long_dense_arc_welds_to_few_lines_within_the_tolerance():
    """2,000 G1 lines along a circle of radius 100 mm in 3-decimal steps become a handful of arcs, every
    one within the tolerance measured on the output as read back."""
    t = np.linspace(0.0, 1.2 * np.pi, 2001)
    moves = [f"G1 X{100 * np.cos(a):.3f} Y{100 * np.sin(a):.3f}" for a in t]
    text = "\n".join(["G21 G90 G17", "G0 X100 Y0", "G1 Z-1 F300", moves[0] + " F1200", *moves[1:], "G0 Z5",
                      "M30"]) + "\n"
    program = read_text(text)
    out, records, _, _, kept = weld_arcs(program, program, 0.01)
    assert len(out.splitlines()) <= 10 and kept == 0
    assert _deviation(text, out) <= 0.01


def test_an_arc_the_screen_chose_but_its_own_measure_rejects_is_counted(monkeypatch):
    """An arc is measured again as it is written before it is used; one that fails there stays as its G1
    lines and is counted with the arcs kept as lines, not dropped unseen."""
    from toolpath.smooth import arc_weld

    text = polygon_program(60)
    program = read_text(text)
    _, chosen, _, _, kept = weld_arcs(program, program, 0.01)
    assert chosen and kept == 0
    monkeypatch.setattr(arc_weld, "_within", lambda *_: None)
    out, records, _, _, kept = weld_arcs(program, program, 0.01)
    assert records == [] and kept == len(chosen) and out == text


@pytest.mark.parametrize("seed", range(4))
def test_the_compiled_screen_gives_the_numpy_screens_bounds_to_the_bit(seed, monkeypatch):
    """The screen's compiled loops (numba, the fast extra; large batches only) and its NumPy arrays give every
    candidate the same bound to the last bit; with a budget, the loops stop a candidate past it, and each
    candidate fits (bound <= budget) under both or neither."""
    from toolpath.smooth import arc_search

    if arc_search.compiled_kernels() is None:
        pytest.skip("numba is not installed (the fast extra): the compiled loops are not there to test")
    rng = np.random.default_rng(seed)
    n, size = 40, 24
    t = np.cumsum(rng.uniform(0.02, 0.1, n))
    xy = np.round(np.column_stack([6.0 * np.cos(t), 6.0 * np.sin(t)]) + rng.normal(0.0, 0.004, (n, 2)), 3)
    chain = arc_search.Chain(xy, xy + rng.normal(0.0, 0.002, (n, 2)), xy, np.ones(n), np.full(n, 3), np.ones(n))
    starts = np.array([0, 5, 11])
    index = starts[:, None] + np.arange(size + 1)[None, :]
    p = xy[index] - xy[starts][:, None, :]
    o = chain.original[index] - xy[starts][:, None, :]
    rows, k = np.divmod(np.arange(len(starts) * size), size)
    centre = -xy[starts][rows] * rng.uniform(0.999, 1.001, (len(rows), 1))
    args = (chain, starts, index, p, o, rows, centre, k + 1)
    monkeypatch.setattr(arc_search, "COMPILED_CELLS", 0)  # a batch this small: in compiled loops all the same
    compiled = arc_search._bound(*args)
    monkeypatch.setattr(arc_search, "compiled_kernels", lambda: None)
    plain = arc_search._bound(*args)
    assert np.isfinite(plain).sum() >= 10  # arcs measured, not only refused
    assert np.array_equal(compiled, plain)
    budget = float(np.median(plain[np.isfinite(plain)]))
    monkeypatch.undo()
    monkeypatch.setattr(arc_search, "COMPILED_CELLS", 0)
    stopped = arc_search._bound(*args, budget)
    assert np.array_equal(stopped <= budget, plain <= budget)
    assert np.array_equal(stopped[plain <= budget], plain[plain <= budget])


def test_arcs_without_numba_are_the_arcs_with_it(monkeypatch):
    """The core install (no numba) welds the same arcs with the same figures: a long noisy arc whose check
    runs pieced (the compiled measure where numba is installed) and the screen's bounds, both paths; a chain
    long enough for the compiled loops' longer windows (arc_search.COMPILED_LAST_WINDOW) on one, NumPy's on
    the other."""
    import importlib

    from toolpath.smooth import arc_search

    hausdorff_module = importlib.import_module("toolpath.geometry.hausdorff")  # the package exports a function
    arc_weld_module = importlib.import_module("toolpath.smooth.arc_weld")
    if arc_search.compiled_kernels() is None or hausdorff_module.compiled_kernels() is None:
        pytest.skip("numba is not installed (the fast extra): only the NumPy path is there")
    rng = np.random.default_rng(3)
    count = COMPILED_POINTS + 100
    t = np.linspace(0.0, 2.5 * count / 1500, count)
    pts = np.column_stack([40.0 * np.cos(t), 40.0 * np.sin(t)]) + rng.normal(0.0, 0.002, (count, 2))
    text = "G21 G90 G17\nG0 X40 Y0\nG1 Z-1 F300\n" + "".join(f"G1 X{x:.4f} Y{y:.4f}\n" for x, y in pts) + "M30\n"
    program = read_text(text)
    monkeypatch.setattr(arc_search, "COMPILED_CELLS", 0)  # every batch of the screen in compiled loops
    chains = []
    search = arc_weld_module.fewest_blocks
    monkeypatch.setattr(arc_weld_module, "fewest_blocks", lambda chain, *a: chains.append(chain) or search(chain, *a))
    compiled = weld_arcs(program, program, 0.01)
    assert chains and all(chain.compiled for chain in chains)  # the compiled loops' windows
    assert any(r.lines_replaced > 400 for r in compiled[1])  # long enough to be measured in pieces
    monkeypatch.setattr(arc_search, "compiled_kernels", lambda: None)
    monkeypatch.setattr(hausdorff_module, "compiled_kernels", lambda: None)
    plain = weld_arcs(program, program, 0.01)
    assert plain[0] == compiled[0]
    assert [r.deviation_mm for r in plain[1]] == pytest.approx([r.deviation_mm for r in compiled[1]], rel=1e-12)


def test_a_parameter_line_with_the_letter_f_beside_a_run_is_left_unread():
    """Lines an arc may not replace are never tokenized for an F word: ``#<z_safe> = 5`` (an f in its name)
    once stopped the whole program ('#' parameters are read by the interpreter, not by the word lexer)."""
    text = polygon_program(60).replace("G21 G90 G17\n", "G21 G90 G17\n#<z_safe> = 5\n(feed and safe height)\n")
    welded = _weld_text(text)
    assert "#<z_safe> = 5\n" in welded and "(feed and safe height)\n" in welded
    assert _deviation(text, welded) <= 0.01 + 1e-9


@pytest.mark.skipif(not CORPUS.is_dir(), reason="../shared/gcode-corpus is absent (real CAM programs)")
def test_every_corpus_program_welds_arcs_alone_without_a_refusal(tmp_path):
    """Arcs alone (``--method none --arcs``) on every shared corpus program: exit 0 and a report, whatever
    the program holds (parameters, comments, inch units, G91); the two in the test above are measured too."""
    from toolpath.smooth.command import main

    measured = {"camotics_tiny_cat_outline.ngc", "tinyg_hacdc.gcode"}
    for source in sorted(p for p in CORPUS.iterdir() if p.suffix != ".md" and p.name not in measured):
        report = tmp_path / f"{source.name}.json"
        assert main([str(source), "-o", str(tmp_path / source.name), "--arcs", "--method", "none",
                     "--units", "mm", "--report", str(report)]) == 0, source.name
        assert json.loads(report.read_text())["largest_deviation_mm"] <= 0.01


@pytest.mark.parametrize("seed", range(3))
def test_the_compiled_screen_fits_the_ends_the_numpy_screen_fits(seed, monkeypatch):
    """The whole screen of a batch of starts in compiled loops (least squares, minimax and flattest centres, one
    candidate at a time) fits the very ends the NumPy arrays fit, about the same centres (their sums run in
    another order); noisy steps make all three centre kinds answer."""
    from toolpath.smooth import arc_search

    if arc_search.compiled_kernels() is None:
        pytest.skip("numba is not installed (the fast extra): the compiled loops are not there to test")
    rng = np.random.default_rng(seed)
    n = 160
    t = np.cumsum(rng.uniform(0.01, 0.03, n))
    xy = np.column_stack([20.0 * np.cos(t), 20.0 * np.sin(t)]) + [100.0, -40.0]
    xy[60:110] = np.linspace(xy[60], xy[110], 50) + rng.normal(0.0, 0.003, (50, 2))  # a straight edge in steps
    xy = np.round(xy + rng.normal(0.0, 0.002, (n, 2)), 3)
    chain = arc_search.Chain(xy, xy, xy, np.ones(n), np.full(n, 3), np.ones(n))
    starts = np.array([0, 7, 40, 61, 90])
    j = np.tile(np.arange(2, 66), (len(starts), 1))
    valid = rng.random(j.shape) < 0.9
    args = (chain, starts, j, valid, n - 1, 0.006, 2, 1e4)
    monkeypatch.setattr(arc_search, "COMPILED_CELLS", 0)
    fits, centres = arc_search._measure_ends(*args)
    monkeypatch.setattr(arc_search, "compiled_kernels", lambda: None)
    plain_fits, plain_centres = arc_search._measure_ends(*args)
    assert 0 < plain_fits.sum() < valid.sum()  # some ends fit, some do not
    assert np.array_equal(fits, plain_fits)
    assert np.allclose(centres[fits], plain_centres[fits], rtol=0.0, atol=1e-9)


def test_a_probe_short_of_the_longest_arc_measures_the_window_last_end_alone(monkeypatch):
    """Inside a long arc a window's probe costs one end (its last, which fits) until the longest arc's window,
    whose last ends are where arcs end and are all measured: the same arcs as measuring every end."""
    from toolpath.smooth import arc_search

    t = np.linspace(0.0, 1.5, 1201)
    xy = np.round(np.column_stack([100 * np.cos(t), 100 * np.sin(t)]), 3)
    n = len(xy)
    chain = arc_search.Chain(xy, xy, xy, np.ones(n), np.full(n, 3), np.ones(n))
    measured_ends = []
    screen = arc_search._measure_ends

    def counting(chain, starts, j, valid, *args):
        measured_ends.extend(j[0][valid[0]].tolist() if starts[0] == 0 else [])
        return screen(chain, starts, j, valid, *args)

    monkeypatch.setattr(arc_search, "_measure_ends", counting)
    probed = arc_search.fewest_blocks(chain, n - 1, 0.01, 2, 1000, 1e4, 8)
    # from the first point (its first end: 2) the windows doubling up to 256 ends: those ending at 113, 241,
    # 497 and 753 probe one end each; the longest arc's window (ending at 1000) probes its last nine
    assert [j for j in measured_ends if j >= arc_search.GALLOP] == [113, 241, 497, 753, *range(992, 1001)]
    monkeypatch.setattr(arc_search, "GALLOP", 10 ** 6)
    assert [(i, q) for i, q, _ in probed] == [(i, q) for i, q, _ in arc_search.fewest_blocks(
        chain, n - 1, 0.01, 2, 1000, 1e4, 8)]


@pytest.mark.parametrize("comment", ["(plain ascii)", "(café, ü)"])
def test_lines_holding_and_occurs_find_each_line_as_a_search_line_by_line_would(comment):
    """The characters' lines found in one vectorised pass (ASCII text) or by a regex (any other) and a
    pattern searched only in the lines the scanner did not read as plain G0 / G1 moves: line by line alike."""
    from toolpath.smooth.arc_runs import _INVERSE_TIME, lines_holding, occurs

    text = ("G21 G90\nG1 X1 Y1 F100\n" + comment + "\n/G1 X2\nG1 X3 ; done\nG1 X4 F200\n"
            + "G1 X5 Y5\n" * 50 + "G1 X6 G 093 F2\nG0 X0\n")
    program = read_text(text)
    for chars in ("/(;", "Ff"):
        by_line = [False] + [bool(re.search(f"[{re.escape(chars)}]", line)) for line in program.lines]
        assert lines_holding(program, chars).tolist() == by_line
    assert occurs(program, _INVERSE_TIME) and not occurs(read_text(text.replace("G 093", "G94")), _INVERSE_TIME)
