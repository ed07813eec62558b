"""Parametric outlines and CAM passes: closed, of the configured size, simple, deterministic."""

import math

import numpy as np
import pytest
from shapely.geometry import LinearRing

from toolpath.geometry import point_to_polyline
from toolpath.shapes import Roughness, discretise, gear, maple_leaf, offset_passes, pentagram, roughen, synthesize
from toolpath.shapes.synth import draw

SPECS = {
    "gear": {"module": 2.0, "teeth": 20, "pressure_angle": 20.0, "addendum": 1.0, "dedendum": 1.25,
             "root_fillet": 0.38},
    "pentagram": {"outer_radius": 30.0, "inner_ratio": 0.45, "tip_fillet": 1.0, "valley_fillet": 2.0},
    "maple_leaf": {"size": 60.0, "serrations": 40, "serration_depth": 0.03, "lobe_depth": 0.5,
                   "lobe_sharpness": 1.5},
}
CAM = {"tool_diameter": 2.0, "finish_stock": 0.2, "stepover": 0.4, "roughing_passes": 2, "depth": 2.0,
       "rotation": [0.0, 360.0], "stay_down": 0.5}
ROUGH = {"chord_tolerance": 0.002, "max_segment": 0.5, "tiny_segment_rate": 0.05,
         "tiny_segment_length": 0.001, "noise_probability": 1.0, "noise_amplitude": 0.002, "noise_span": 0,
         "noise_duty": 1.0}


def test_gear_has_the_configured_tip_and_root_radius():
    g = gear(module=2.0, teeth=20, root_fillet=0.38)
    r = np.hypot(*np.asarray(g.exterior.coords).T)
    assert r.max() == pytest.approx(2.0 * (20 / 2 + 1.0), rel=1e-6)  # tip radius m (z/2 + ha)
    assert r.min() == pytest.approx(2.0 * (20 / 2 - 1.25), rel=1e-3)  # root radius m (z/2 - hf)
    assert g.exterior.is_simple and g.is_valid


def test_gear_has_one_tooth_per_tooth():
    g = gear(module=1.0, teeth=17)
    coords = np.asarray(g.exterior.coords)
    r = np.hypot(*coords.T)
    on_tip = r > r.max() - 1e-6
    runs = np.count_nonzero(np.diff(on_tip.astype(int)) == 1) + (on_tip[0] and not on_tip[-2])
    assert runs == 17


def test_pentagram_tips_reach_outer_radius_without_fillet_and_fillets_shrink_them():
    sharp = pentagram(30.0, 0.382)
    assert np.hypot(*np.asarray(sharp.exterior.coords).T).max() == pytest.approx(30.0)
    rounded = pentagram(30.0, 0.382, tip_fillet=2.0, valley_fillet=2.0)
    assert np.hypot(*np.asarray(rounded.exterior.coords).T).max() < 30.0 - 1.0
    assert rounded.exterior.is_simple


def test_maple_leaf_is_simple_and_of_configured_size():
    leaf = maple_leaf(60.0, serrations=40, serration_depth=0.03)
    r = np.hypot(*np.asarray(leaf.exterior.coords).T)
    assert r.max() <= 30.0 * 1.03 + 1e-9 and r.max() > 30.0 * 0.95
    assert leaf.exterior.is_simple and leaf.is_valid


@pytest.mark.parametrize("shape", list(SPECS))
def test_synthesized_passes_are_closed_simple_and_deterministic(shape):
    clean = {**ROUGH, "noise_probability": 0.0}
    passes, drawn = synthesize(shape, SPECS[shape], CAM, clean, np.random.default_rng(7))
    again, _ = synthesize(shape, SPECS[shape], CAM, clean, np.random.default_rng(7))
    assert len(passes) == 3  # two roughing passes and the finishing pass
    for p, q in zip(passes, again, strict=True):
        assert np.array_equal(p.xy, q.xy)
        assert np.array_equal(p.xy[0], p.xy[-1])  # closed
        assert LinearRing(p.xy).is_simple
    assert drawn["roughness.noise"] == 0.0


@pytest.mark.parametrize("shape", list(SPECS))
def test_noise_stays_within_its_stated_amplitude(shape):
    clean, _ = synthesize(shape, SPECS[shape], CAM, {**ROUGH, "noise_probability": 0.0}, np.random.default_rng(7))
    noisy, drawn = synthesize(shape, SPECS[shape], CAM, ROUGH, np.random.default_rng(7))
    assert drawn["roughness.noise"] == 0.002
    for p, q in zip(clean, noisy, strict=True):
        dev = point_to_polyline(q.xy, p.xy)
        assert dev.max() < 6 * 0.002 and dev.mean() > 0.0005  # noise present, within 6 sigma


def test_offset_passes_are_outermost_first_and_clockwise():
    part = pentagram(20.0, 0.45, 1.0, 1.0)
    rings = offset_passes(part, tool_radius=1.0, finish_stock=0.2, stepover=0.8, roughing_passes=2)
    areas = [LinearRing(r).convex_hull.area for r in rings]
    assert areas == sorted(areas, reverse=True)
    assert not any(LinearRing(r).is_ccw for r in rings)


def test_chordal_discretisation_respects_the_tolerance():
    t = np.linspace(0, 2 * math.pi, 20001)
    circle = 10.0 * np.column_stack([np.cos(t), np.sin(t)])
    coarse = discretise(circle, chord_tolerance=0.01, max_segment=math.inf)
    step = 2 * math.acos(1 - 0.01 / 10.0)
    assert len(coarse) - 1 >= math.ceil(2 * math.pi / step) - 1  # no fewer chords than the sagitta allows
    mid = (coarse[1:] + coarse[:-1]) / 2
    assert np.all(10.0 - np.hypot(*mid.T) <= 0.01 + 1e-9)
    split = discretise(circle, chord_tolerance=0.01, max_segment=0.1)
    assert np.linalg.norm(np.diff(split, axis=0), axis=1).max() <= 0.1 + 1e-9


def test_roughen_keeps_the_closure_and_adds_tiny_segments():
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], dtype=float)
    rough = roughen(square, Roughness(0.001, 1.0, 1.0, 0.001, 0.0), np.random.default_rng(0))
    assert len(rough) == 9 and np.array_equal(rough[0], rough[-1])
    assert np.sort(np.linalg.norm(np.diff(rough, axis=0), axis=1))[:4] == pytest.approx([0.001] * 4)


def test_draw_forms():
    rng = np.random.default_rng(0)
    assert draw(3.5, rng) == 3.5
    assert isinstance(draw([1, 4], rng), int)
    assert 0.001 <= draw({"log": [0.001, 0.1]}, rng) <= 0.1
