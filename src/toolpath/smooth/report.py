"""The report of ``toolpath smooth``: per window and per program, as JSON or as an HTML page that
draws the path before and after with the rough windows marked."""

from __future__ import annotations

import html
import io
import json
from collections import Counter
from dataclasses import asdict
from pathlib import Path

import numpy as np

from toolpath.geometry.labels.categories import CATEGORY_NAMES

_TIME_NOTE = ("feed planner (seed 002) under the default machine limits, feed moves only; rapids are not timed; "
              "a run longer than a part (~8 MB of text) is planned in pieces, each from rest to rest")


def summary(args, lines: int, result, times: tuple, machine: dict) -> dict:
    """Everything a machinist checks before running the new program."""
    before, after, why = times
    windows = result.windows
    arcs = result.arcs or []
    statuses = Counter("kept" if w.status.startswith("kept") else w.status for w in windows)
    return {
        "input": str(args.input), "output": str(args.input if args.in_place else args.output),
        "tolerance_mm": args.tolerance, "classifier": args.classifier, "method": args.method, "seed": args.seed,
        "lines": lines, "lines_changed": len(result.changed_lines),
        "windows": {"total": len(windows), "smoothed": statuses.get("smoothed", 0),
                    "smooth_already": statuses.get("smooth already", 0), "kept": statuses.get("kept", 0),
                    "per_category": {f"{c} {CATEGORY_NAMES[c - 1]}": sum(w.category == c for w in windows)
                                     for c in (1, 2, 3, 4)},
                    "kept_reasons": dict(Counter(w.status[len("kept: "):] for w in windows
                                                 if w.status.startswith("kept")))},
        # a long program is smoothed in parts; where lines setting a parameter, G28.1/G30.1, G90.1/G91.1
        # or a G6.2 block sit at a part's end, the windows of the run open there restart (optimize.stream)
        "parts": {"count": result.parts,
                  "windows_restart_at_lines": list(result.restarts)},
        # every construct the reader read past (toolpath.gcode.passing), copied through as written
        "passed_through": list(getattr(result, "passed", [])),
        "largest_deviation_mm": max([w.deviation_mm for w in windows] + [a.deviation_mm for a in arcs], default=0.0),
        **({"arcs": {"fitted": len(arcs), "lines_replaced": sum(a.lines_replaced for a in arcs),
                     "largest_deviation_mm": max((a.deviation_mm for a in arcs), default=0.0),
                     "not_fitted_because": result.arcs_note,
                     "kept_as_lines": getattr(result, "arcs_kept_as_lines", 0),  # rejected as written or by the check
                     "rows": [asdict(a) for a in arcs]}}
           if getattr(args, "arcs", False) else {}),
        "machining_time_s": {"before": before, "after": after,
                             "saved_pct": None if not before or after is None else 100.0 * (1 - after / before),
                             "not_planned_because": why,
                             "machine": machine, "note": _TIME_NOTE + ("; arcs planned as chords within the "
                                                                        "planner's blend tolerance"
                                                                        if getattr(args, "arcs", False) else "")},
        # per-window rows only where a report is written (a million-line program has 20,000 windows)
        "window_rows": [{name: getattr(w, name) for name in w.__slots__} for w in windows]
        if getattr(args, "report", None) is not None else [],
    }


def write_report(fh, suffix: str, report: dict, result) -> None:
    """The report into the binary file ``fh``: HTML (the path drawn) for ``.html``, else JSON."""
    fh.write((_html(report, result) if suffix == ".html" else _json(report)).encode("utf-8"))


def _json(report: dict) -> str:
    """Indented JSON with one line per window row: readable, and written by the C encoder (the indented
    encoder is pure Python, seconds for the 20,000 rows of a million-line program)."""
    rows = report.get("window_rows") or []
    text = json.dumps({**report, "window_rows": []}, indent=2, default=_plain)
    if rows:
        body = ",\n".join("    " + json.dumps(row, default=_plain) for row in rows)
        text = text.replace('\n  "window_rows": []', '\n  "window_rows": [\n' + body + "\n  ]", 1)
    return text + "\n"


def _plain(value):
    """numpy scalars as Python numbers (anything else is a bug worth its TypeError)."""
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"{type(value).__name__} in a smooth report")


def write_plot(fh, suffix: str, result) -> None:
    """The path before and after, rough windows marked, into the binary file ``fh``: PNG or SVG (``suffix``)."""
    fig = _figure(result, result.windows)
    fig.savefig(fh, format=suffix.lstrip("."), bbox_inches="tight", dpi=150)
    import matplotlib.pyplot as plt

    plt.close(fig)


def _figure_svg(result, windows) -> str:
    import matplotlib.pyplot as plt

    with plt.rc_context({"svg.hashsalt": "toolpath smooth"}):  # fixed element ids: the same bytes every run
        fig = _figure(result, windows)
        out = io.StringIO()
        fig.savefig(out, format="svg", bbox_inches="tight", metadata={"Date": None})
    plt.close(fig)
    return out.getvalue()


#: the colour of each rough category's windows, in the drawing and its legend
_CATEGORY_COLOURS = {2: "tab:orange", 3: "tab:red", 4: "purple"}


def _largest_change(result) -> tuple[np.ndarray, float] | None:
    """Where a point moved most (its position before) and by how much (mm); None when nothing moved."""
    best = None
    for before, after in zip(result.runs_before, result.runs_after, strict=True):
        if len(before) != len(after) or not len(before):
            continue
        moved = np.hypot(*(after - before).T)
        k = int(moved.argmax())
        if moved[k] > 0 and (best is None or moved[k] > best[1]):
            best = (before[k], float(moved[k]))
    return best


def _figure(result, windows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 7))
    for k, xy in enumerate(result.runs_before):
        ax.plot(xy[:, 0], xy[:, 1], color="0.6", lw=1.6, label="before" if k == 0 else None)
    for k, xy in enumerate(result.runs_after):
        ax.plot(xy[:, 0], xy[:, 1], color="tab:blue", lw=0.7, label="after" if k == 0 else None)
    size, seen, drawn = 50, Counter(), set()
    for w in windows:
        index = seen[w.run]
        seen[w.run] += 1
        if w.category >= 2:
            xy = result.runs_before[w.run][index * size:(index + 1) * size]
            name = f"rough window, category {w.category} ({CATEGORY_NAMES[w.category - 1]})"
            ax.plot(xy[:, 0], xy[:, 1], color=_CATEGORY_COLOURS[w.category], lw=2.5, alpha=0.35,
                    label=name if w.category not in drawn else None)
            drawn.add(w.category)
    if (change := _largest_change(result)) is not None:  # at the tolerance the paths lie on each other: zoom in
        (cx, cy), moved = change
        half = 12 * moved
        inset = ax.inset_axes([0.64, 0.04, 0.34, 0.34])
        for runs, colour, width in ((result.runs_before, "0.45", 1.6), (result.runs_after, "tab:blue", 1.0)):
            for xy in runs:
                inset.plot(xy[:, 0], xy[:, 1], color=colour, lw=width, marker=".", ms=4)
        inset.set_xlim(cx - half, cx + half)
        inset.set_ylim(cy - half, cy + half)
        inset.set_aspect("equal")
        inset.tick_params(labelsize=6)
        inset.set_title(f"the largest change, {1000 * moved:.1f} µm, at true scale", fontsize=7)
        ax.indicate_inset_zoom(inset, edgecolor="0.3")
    ax.set_aspect("equal")
    ax.set_xlabel("X (mm)")
    ax.set_ylabel("Y (mm)")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("feed moves before and after smoothing")
    return fig


def _cell(value) -> str:
    """A report value as a table cell reads it: a mapping as ``key: value; ..``, a list comma-separated,
    nothing as "none" (not Python's None)."""
    if value is None:
        return "none"
    if isinstance(value, dict):
        return "; ".join(f"{k}: {_cell(v)}" for k, v in value.items()) or "none"
    if isinstance(value, list | tuple):
        return ", ".join(_cell(v) for v in value) or "none"
    return str(value)


def _rounded(key: str, value):
    """A figure as it means something: millimetres to the micron, per cents to a tenth, seconds to the
    millisecond, other fractions to four significant digits."""
    if not isinstance(value, float):
        return value
    if key.endswith("_mm") or "(mm)" in key:
        return f"{value:.3f}"
    if "pct" in key or "(%)" in key:
        return f"{value:.1f}"
    if "(s)" in key or key.endswith("_s"):
        return f"{value:.3f}"
    return f"{value:.4g}"


def _html(report: dict, result) -> str:
    e = html.escape
    head = {k: v for k, v in report.items() if k not in ("window_rows", "windows", "machining_time_s", "arcs")}
    if "arcs" in report:
        head |= {f"arcs {k}": v for k, v in report["arcs"].items() if k != "rows"}
    t = report["machining_time_s"]
    rows = "".join(
        f"<tr><td>{w['first_line']}-{w['last_line']}</td><td>{w['category']}</td><td>{e(w['method'])}</td>"
        f"<td>{w['curvature_before']:.3f}</td><td>{w['curvature_after']:.3f}</td><td>{w['deviation_mm']:.3f}</td>"
        f"<td>{w['lines_changed']}</td><td>{e(w['status'])}</td></tr>" for w in report["window_rows"])
    facts = "".join(f"<tr><th>{e(str(k))}</th><td>{e(_cell(_rounded(str(k), v)))}</td></tr>" for k, v in
                    {**head, **report["windows"], "time before (s)": t["before"], "time after (s)": t["after"],
                     "time saved (%)": t["saved_pct"]}.items())
    name = Path(report["input"]).name
    return (f"<!doctype html><html><head><meta charset='utf-8'><title>toolpath smooth: {e(name)}</title>"
            "<style>body{font-family:sans-serif;margin:2em}table{border-collapse:collapse}td,th{border:1px solid #ccc;"
            "padding:2px 6px;text-align:left}</style></head><body>"
            f"<h1>toolpath smooth: {e(name)}</h1><p>{e(report['input'])} -> {e(report['output'])}</p>"
            f"<table>{facts}</table>"
            f"{_figure_svg(result, result.windows)}<h2>Windows</h2><table><tr><th>lines</th><th>category</th>"
            "<th>method</th><th>LocalCurvature before</th><th>after</th><th>two-sided deviation (mm)</th>"
            f"<th>lines changed</th><th>status</th></tr>{rows}</table></body></html>\n")
