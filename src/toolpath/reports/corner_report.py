"""The NURBS corner paper's results in the report: the corner cases, the FDLS / SDLS surrogates, the machining time
each optimisation method saves, the feed profiles and the surrogates' training curves."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from toolpath.reports.paper import NURBS_CORNER_PAPER  # noqa: E402
from toolpath.reports.tables import Table  # noqa: E402

METHOD_NAMES = {"nurbs_pso": "NURBS + PSO (NURBS corner paper)", "nurbs_net": "NURBS + FDLS/SDLS (NURBS corner paper)",
                "bspline": "cubic B-spline (Zhao 2013)", "bezier": "G2 dual Bezier (Bi 2015)"}


def _num(value: float | None, fmt: str) -> str:
    return "-" if value is None else f"{value:{fmt}}"


def cases_table(metrics: Mapping, rows: Sequence[Mapping[str, str]] = (), delta_max: float | None = None,
                band: float | None = 0.0) -> Table:
    """Per case and method: curvature reduction (mean / worst / best, against the circular blend and
    against method 1), two-sided error, inside-ness, time, its bounds and the time saved; ``rows`` (the
    corner rows) give the W note the largest reduction any curve could reach; ``band``: the planner's
    reading of a smooth curve (``feedrate.band``), named in the note."""
    table = Table("NURBS corner paper, cases 1-3: corner smoothing and machining time, ours (paper)",
                  ["case", "method", "corners (kept sharp)", "reduction vs arc: mean / worst / best %",
                   "reduction vs method 1: mean / worst / best %", "max two-sided error / mm", "all inside",
                   "time / s", "toppra lower bound / s", "saved vs G01 / %", "saved vs B-spline / %",
                   "saved vs Bezier / %", "limits kept"])
    for case, rec in metrics["cases"].items():
        table.add([case, "G01 with controller blend", "-", "-", "-", "-", "-", f"{rec['g01']['time']:.3f}",
                   _num(rec["g01"].get("lower_bound"), ".3f"), "-", "-", "-",
                   "yes" if rec["g01"]["within_limits"] else "NO"])
        for method, r in rec["methods"].items():
            reduction = _spread(r, "")
            if case == "w" and method == "nurbs_pso":
                reduction += f" (best: {NURBS_CORNER_PAPER['w_max_reduction_pct']})"
            vs = r["time_saved_vs_pct"]
            bs, bz = _num(vs.get("bspline"), "+.1f"), _num(vs.get("bezier"), "+.1f")
            if case == "dress" and method == "nurbs_pso":
                bs += f" ({NURBS_CORNER_PAPER['dress_saved_vs_ref20_pct']})"
                bz += f" ({NURBS_CORNER_PAPER['dress_saved_vs_ref21_pct']})"
            counts = f"{r['corners']} ({r['kept_sharp']}){_families(r)}"
            table.add([case, METHOD_NAMES.get(method, method), counts, reduction,
                       _spread(r, "_vs_method1"), _num(r["max_error_mm"], ".3f"), "yes" if r["all_inside"] else "NO",
                       f"{r['time']:.3f}", _num(r.get("lower_bound"), ".3f"),
                       f"{r['time_saved_vs_g01_pct']:+.1f}", bs, bz, "yes" if r["within_limits"] else "NO"])
    table.notes.append(
        "Peak-curvature reduction per corner, mean / worst / best over the smoothed corners, against two 'befores' "
        "(the sharp corner has no finite curvature and the paper does not say what its 'before' is): the circular "
        "blend within the same delta_max (the physical reference) and method 1's five-point NURBS on the same legs "
        "held to the same delta_max (what FDLS takes as the curve before smoothing); negative means sharper. "
        "Error: the exact two-sided distance between each curve and the two legs it replaces; every curve must lie "
        "inside its corner. "
        "The paper's figures (in brackets) are its W case's largest reduction and its dress case's time saved against "
        "its refs. 20 / 21, which are not the transitions we compare with. Times are the NURBS corner paper's planner "
        f"({_reading(band)}, S-curve ramps under the tangential acceleration and jerk limits; a G01 vertex at its "
        "limit on the controller's blend arc); the toppra bound has no jerk limit. "
        "'Kept sharp': corners no curve met Eq. 7 on (too little room), planned with the controller blend. "
        "NURBS + PSO's swarm holds method 1 at delta_max and the dual Bezier as its first best, so it is never "
        "sharper than either; in brackets after its count, the corners where one of them stayed best (method 2 was "
        "not flatter there).")
    table.notes += _against_paper(metrics, rows, delta_max)
    return table


def _reading(band: float | None) -> str:
    """How the planner read a smooth curve's limits (``feedrate.band``; choice 1 of toolpath.feedrate.planner)."""
    if band is None:
        return "the paper's rule: each sensitive interval at its lowest limit"
    if band == 0:
        return "read point by point: each sample of a curve at its own limit (feedrate.band 0)"
    return f"a sensitive interval cut where its limit varies by more than {band:g} (feedrate.band)"


def _families(r: Mapping) -> str:
    """', 7 dual Bezier, 1 method 1' for the corners whose answer is a reference curve of PSO's swarm."""
    kept = [f"{count} {source.removeprefix('pso: ')}" for source, count in r.get("answers", {}).items()
            if source.startswith("pso: ") and count]
    return f" [{', '.join(kept)}]" if kept else ""


def _spread(r: Mapping, suffix: str) -> str:
    keys = (f"mean_reduction{suffix}_pct", f"worst_reduction{suffix}_pct", f"max_reduction{suffix}_pct")
    return " / ".join(_num(r.get(k), ".1f") for k in keys)


def pso_study_table(metrics: Mapping) -> Table:
    """PSO's convergence study: mean and worst peak curvature relative to the best found, per size."""
    study = metrics["pso_study"]
    table = Table("PSO size (Eq. 8): peak curvature relative to the best any size found, mean / worst over "
                  f"{study['solved']} drawn corners", ["particles", "iterations", "evaluations", "mean", "worst"])
    for r in study["settings"]:
        table.add([r["particles"], r["iterations"], r["evaluations"], f"{r['mean_relative_curvature']:.3f}",
                   f"{r['worst_relative_curvature']:.3f}"])
    best = study["cheapest_within_enough"]
    if best:
        table.notes.append(f"The cheapest size within {100 * study['enough']:.0f} % of the best on average: "
                           f"{best['particles']} particles x {best['iterations']} iterations "
                           f"({best['evaluations']} evaluations); beyond it more no longer helps on these corners.")
    return table


def flattest_curvature(turn_deg: float, delta_max: float) -> float:
    """The curvature of the circular arc tangent to both legs of a corner turning ``turn_deg`` whose
    middle is ``delta_max`` from the corner: with the legs' opening alpha = 180 deg - turn, the centre
    on the bisector at d = delta / (1 - sin(alpha / 2)) and radius d sin(alpha / 2), so
    kappa = (1 - sin(alpha / 2)) / (delta sin(alpha / 2)) (a square corner: (sqrt 2 - 1) / delta)."""
    half = math.radians(180.0 - turn_deg) / 2.0
    return (1.0 - math.sin(half)) / (delta_max * math.sin(half))


def arc_bound(rows: Sequence[Mapping[str, str]], case: str, delta_max: float) -> float | None:
    """The largest peak-curvature reduction against method 1 (at delta_max) that any curve could reach on
    ``case``'s corners, per cent: a curve that leaves and rejoins along the legs and passes within
    delta_max of the corner is nowhere flatter than :func:`flattest_curvature` (one whose curvature stayed
    below the arc's would turn on a wider circle and miss the corner by more), so
    1 - that / method 1 bounds every method's reduction there, whatever room the legs give."""
    bounds = [100.0 * (1.0 - flattest_curvature(float(r["turn_deg"]), delta_max) / float(r["curvature_method1"]))
              for r in rows if r["case"] == case and r["method"] == "nurbs_pso"
              and r["curvature_method1"] not in ("", "nan")]
    return max(bounds, default=None)


def _against_paper(metrics: Mapping, rows: Sequence[Mapping[str, str]] = (), delta_max: float | None = None
                   ) -> list[str]:
    """Where ours is worse than the paper's figure, say so (and, for W, how far any curve could go)."""
    notes = []
    w = metrics["cases"].get("w", {}).get("methods", {}).get("nurbs_pso")
    if w and w["max_reduction_pct"] is not None:
        ours, paper = w["max_reduction_pct"], NURBS_CORNER_PAPER["w_max_reduction_pct"]
        notes.append(f"W: our largest reduction by NURBS + PSO is {ours:.1f} % against the arc and "
                     f"{_num(w['max_reduction_vs_method1_pct'], '.1f')} % against method 1, "
                     f"{'below' if max(ours, w['max_reduction_vs_method1_pct'] or -1e9) < paper else 'above'} "
                     f"the paper's {paper} % (whose 'before' is not stated); the mean is "
                     f"{_num(w['mean_reduction_pct'], '.1f')} / {_num(w['mean_reduction_vs_method1_pct'], '.1f')} %."
                     + (f" No curve can go beyond {bound:.1f} % against method 1 on this path: the circular blend "
                        "within delta_max is the flattest curve inside a corner that passes within delta_max of it."
                        if delta_max and (bound := arc_bound(rows, "w", delta_max)) is not None else ""))
    dress = metrics["cases"].get("dress", {}).get("methods", {}).get("nurbs_pso")
    if dress:
        for other, key in (("bspline", "dress_saved_vs_ref20_pct"), ("bezier", "dress_saved_vs_ref21_pct")):
            saved = dress["time_saved_vs_pct"].get(other)
            if saved is not None:
                verdict = "less than" if saved < NURBS_CORNER_PAPER[key] else "at least"
                notes.append(f"Dress: NURBS + PSO saves {saved:+.1f} % of the time of the {other} transition, "
                             f"{verdict} the {NURBS_CORNER_PAPER[key]} % the paper reports against its ref. "
                             f"{20 if other == 'bspline' else 21}.")
    return notes


def corners_table(rows: list[Mapping[str, str]], case: str, methods: list[str]) -> Table:
    """The NURBS corner paper's Table 2 for one case: each corner's curvature before and after, and its error."""
    table = Table(f"NURBS corner paper, Table 2's content for the {case} path: peak curvature / (1/mm) and two-sided "
                  "error / mm per corner",
                  ["vertex", "turn / deg", "before (arc within delta_max)", "method 1 at delta_max",
                   *(f"{METHOD_NAMES.get(m, m)}" for m in methods)])
    by_vertex: dict[int, dict[str, Mapping[str, str]]] = {}
    for r in rows:
        if r["case"] == case:
            by_vertex.setdefault(int(r["vertex"]), {})[r["method"]] = r
    for vertex, found in sorted(by_vertex.items()):
        first = next(iter(found.values()))
        cells = []
        for m in methods:
            r = found.get(m)
            if r is None:
                cells.append("-")
            elif r["source"].startswith("kept"):
                cells.append("kept sharp" + r["source"].removeprefix("kept"))  # 'kept: why' -> 'kept sharp: why'
            else:
                family = f", {r['source'].removeprefix('pso: ')}" if r["source"].startswith("pso: ") else ""
                cells.append(f"{float(r['curvature_after']):.3f} ({float(r['reduction_pct']):+.1f} % / "
                             f"{float(r['reduction_vs_method1_pct']):+.1f} %), error {float(r['error_mm']):.3f}"
                             f"{family}")
        table.add([vertex, f"{float(first['turn_deg']):.1f}", f"{float(first['curvature_before']):.3f}",
                   f"{float(first['curvature_method1']):.3f}", *cells])
    table.notes.append("In brackets: the reduction against the arc within delta_max / against method 1; a NURBS + PSO "
                       "cell naming a curve family is a corner where that reference of the swarm stayed best. "
                       "The paper's Table 2 (its W "
                       "path, whose dimensions it does not give) reaches a largest reduction of "
                       f"{NURBS_CORNER_PAPER['w_max_reduction_pct']} %.")
    return table


def surrogate_table(metrics: Mapping, timing: Mapping) -> Table:
    s = metrics["surrogates"]
    table = Table("NURBS corner paper, Figs. 6-9: the FDLS / SDLS surrogates on held-out corners",
                  ["networks fitted on", "corners answered", "training corners", "net answer feasible",
                   "repaired weights", "back to PSO", "infeasible", "peak curvature / PSO's", "s per corner: PSO",
                   "s per corner: surrogates"])
    margin = s.get("margin") or {"delta": 0.0, "wedge": 0.0}
    held = margin["delta"] or margin["wedge"]
    rows = [(f"PSO's answers held inside ({s['held_inside']} of {s['train_corners']}: C(1/2) at "
             f"{100 * (1 - margin['delta']):g} % of delta_max, extra point {100 * margin['wedge']:g} % of L in)"
             if held else "PSO's answers as found (the paper's)", s, timing)]
    if "literal" in s:
        rows.append(("PSO's answers as found (the paper's)", s["literal"], timing.get("literal") or {}))
    for label, summary, seconds in rows:
        src, count = summary["sources"], summary["test_corners"]
        table.add([label, f"{count} drawn apart", s["train_corners"],
                   f"{src['net']} ({100 * src['net'] / count:.0f} %)", src["repaired"], src["pso"], src["infeasible"],
                   _num(summary["curvature_ratio_to_pso"], ".3f"), _num(seconds.get("pso_seconds_per_corner"), ".3f"),
                   _num(seconds.get("surrogate_seconds_per_corner"), ".3f")])
    answers = Counter()
    for case in metrics["cases"].values():
        answers.update((case["methods"].get("nurbs_net") or {}).get("answers", {}))
    if total := sum(answers.values()):
        table.add([rows[0][0], f"{total} of the case paths (other paths)", s["train_corners"],
                   f"{answers['net']} ({100 * answers['net'] / total:.0f} %)", answers["repaired"], answers["pso"],
                   answers["infeasible"], "-", "-", "-"])
    table.notes.append("Every surrogate answer is checked against Eq. 7, the inside-the-corner rule and the two-sided "
                       "error, its peak curvature against method 1 at the same delta_max (cur_max); the time per "
                       "corner includes the check, the "
                       "repair and any fall-back to PSO, so it only drops below PSO's when the networks are right "
                       "often. The paper reports its surrogates faster than PSO (ESM Appendix B).")
    if held:
        table.notes.append("PSO's optimum lies on Eq. 7's boundary (C(1/2) exactly delta_max from the corner, the "
                           "curve grazing the leg), so networks fitted on it answer just outside about as often as "
                           "inside; fitted on the same answers held a margin inside, more of their answers pass "
                           "unrepaired, at the peak curvature the margin costs (the ratio to PSO's, both rows on the "
                           "same corners).")
    return table


def windows_table(per_shape: Mapping[str, Mapping], mode: str) -> Table:
    """Machining time saved by each optimisation method on each shape (plain encoding)."""
    methods = sorted({m for d in per_shape.values() for m in d["methods"].get(mode, {}).get("plain", {})})
    table = Table(f"Machining time each method saves on the smoothed windows ({mode} mode): time saved / %, "
                  "largest two-sided distance from the original / mm",
                  ["method", *per_shape])
    for method in methods:
        cells = []
        for d in per_shape.values():
            stats = d["methods"].get(mode, {}).get("plain", {}).get(method)
            cells.append("-" if stats is None else f"{stats['time_saved_pct']:+.1f} / {stats['max_hausdorff_mm']:.3f}"
                         f" ({stats['windows']} windows)")
        table.add([method, *cells])
    table.notes.append("Time of the NURBS corner paper planner over the windows (sum), each window a G01 path with the "
                       "controller blend at its vertices; positive: the smoothed windows run faster.")
    return table


def profiles_figure(profiles: Mapping[str, np.ndarray], cases: list[str], methods: list[str]) -> Figure:
    """Feed against time per case (Figs. 12b-14b), the G01 path and every method."""
    fig, axes = plt.subplots(2, len(cases), figsize=(5.0 * len(cases), 7.0), dpi=110, squeeze=False)
    for col, case in enumerate(cases):
        path = profiles[f"{case}/path"]
        axes[0][col].plot(path[:, 0], path[:, 1], color="0.6", linewidth=2.0, label="G01")
        axes[1][col].plot(profiles[f"{case}/g01/t"], profiles[f"{case}/g01/v"], color="black", linewidth=1.0,
                          label="G01")
        for method in methods:
            p = profiles[f"{case}/{method}/path"]
            axes[0][col].plot(p[:, 0], p[:, 1], linewidth=0.8, label=METHOD_NAMES.get(method, method))
            axes[1][col].plot(profiles[f"{case}/{method}/t"], profiles[f"{case}/{method}/v"], linewidth=0.9,
                              label=METHOD_NAMES.get(method, method))
        axes[0][col].set_aspect("equal")
        axes[0][col].set_title(case)
        axes[1][col].set_xlabel("time / s")
        axes[1][col].set_ylabel("feed / (mm/s)")
    axes[1][0].legend(fontsize=7)
    fig.tight_layout()
    return fig


def training_figure(curves: Mapping[str, np.ndarray]) -> Figure:
    fig, ax = plt.subplots(figsize=(6.0, 3.6), dpi=110)
    for name in ("fdls_mse", "sdls_mse"):
        if name in curves:
            ax.semilogy(curves["epoch"], curves[name], label=name.split("_")[0].upper())
    ax.set_xlabel("epoch")
    ax.set_ylabel("training MSE")
    ax.legend()
    fig.tight_layout()
    return fig
