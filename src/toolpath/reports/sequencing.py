"""Xie & Zhu's Table 1 beside ours, the baselines, the expansion study and a Fig. 10-style sheet drawing."""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from toolpath.reports.paper import XIE_ZHU_TABLE1  # noqa: E402
from toolpath.reports.tables import Table  # noqa: E402

VARIANTS = {"no": "s_shaped_no_avoidance", "yes": "s_shaped"}
BASELINES = ("manual", "nearest_neighbour", "gtsp", "gtsp_eq46", "s_shaped_no_avoidance", "s_shaped")


def _beside(ours: float, paper: float | None, fmt: str) -> str:
    return f"{ours:{fmt}} ({paper:{fmt}})" if paper is not None else f"{ours:{fmt}} (-)"


def sequencing_table(metrics: Mapping, timing: Mapping) -> Table:
    """Xie & Zhu's Table 1: ours (paper) per sheet size, without and with collision avoidance."""
    table = Table("Xie & Zhu, Table 1: S-shaped sequencing, ours (paper)",
                  ["parts", "collision avoidance", "collisions", "manual empty travel / mm", "empty travel / mm",
                   "planning time / s", "optimisation rate / %", "rate vs paper / points"])
    for n, row in sorted(metrics["sheets"].items(), key=lambda kv: int(kv[0])):
        paper = XIE_ZHU_TABLE1.get(int(n), {})
        manual = row.get("manual", {}).get("empty_travel_mm")
        for key, method in VARIANTS.items():
            if method not in row:
                continue
            ours, ref = row[method], paper.get(key)
            rate = ours["optimisation_rate_pct"]
            table.add([n, "yes" if key == "yes" else "no",
                       _beside(ours["collisions"], ref and ref[0], "d"),
                       _beside(manual, ref and ref[1], ".0f") if manual is not None else "-",
                       _beside(ours["empty_travel_mm"], ref and ref[2], ".0f"),
                       _beside(timing[n][method]["seconds"], ref and ref[3], ".2f"),
                       _beside(rate, ref and ref[4], ".1f") if rate is not None else "-",
                       f"{rate - ref[4]:+.1f}" if ref and rate is not None else "-"])
    table.notes.append("Optimisation rate = 1 - empty travel / the manual-like order's empty travel (the paper's "
                       "'average empty travel' of manual sorting). Collisions are counted for every transition "
                       "against every part, not only the planner's collision area. Our sheets are synthetic (the "
                       "paper's sample sets are not published), so only the rates and collision counts compare; "
                       "the paper's time is its planner's time in Python on its PC.")
    return table


def baselines_table(metrics: Mapping) -> Table:
    sizes = sorted(metrics["sheets"], key=int)
    methods = [m for m in BASELINES if all(m in metrics["sheets"][n] for n in sizes)]
    table = Table("Xie & Zhu: empty travel / mm and collisions of every method, per sheet",
                  ["method", *(f"{n} parts" for n in sizes)])
    for m in methods:
        cells = []
        for n in sizes:
            s = metrics["sheets"][n][m]
            best = min(metrics["sheets"][n][k]["empty_travel_mm"] for k in methods
                       if metrics["sheets"][n][k]["collisions"] == 0) if any(
                metrics["sheets"][n][k]["collisions"] == 0 for k in methods) else None
            text = f"{s['empty_travel_mm']:.0f} / {s['collisions']}"
            cells.append(f"**{text}**" if best is not None and s["collisions"] == 0
                         and s["empty_travel_mm"] == best else text)
        table.add([m, *cells])
    table.notes.append("manual: rows bottom to top, in turn left to right and right to left; nearest_neighbour: "
                       "cheapest Eq. 4-6 transition to a near part; gtsp: OR-Tools generalised TSP over entry points "
                       "(leaves a part where it entered, ignores collisions); gtsp_eq46: its order with Eq. 4-6 "
                       "exit / entry points. Bold: the least empty travel with no collision.")
    return table


def expansion_table(metrics: Mapping, sheet: int) -> Table:
    table = Table(f"Xie & Zhu, Fig. 9 as a table: expansion count of the primary region ({sheet} parts)",
                  ["expansions", "empty travel / mm", "collisions"])
    for count, s in sorted(metrics["expansion"].items(), key=lambda kv: int(kv[0])):
        table.add([count, f"{s['empty_travel_mm']:.0f}", s["collisions"]])
    table.notes.append("The paper finds 2 expansions best on its 68-sample set (fewest collisions, shortest path).")
    return table


def _draw(ax, sheet: Mapping, record: Mapping, title: str) -> None:
    for part in sheet["parts"]:
        ring = np.asarray(part["ring"])
        ax.fill(ring[:, 0], ring[:, 1], facecolor="0.9", edgecolor="0.45", linewidth=0.5)
    visits, hits = record["visits"], {k for k, _ in record["collisions"]}
    for k, (a, b) in enumerate(zip(visits[:-1], visits[1:], strict=True)):
        (x0, y0), (x1, y1) = a["exit"], b["entry"]
        colliding = k in hits
        ax.plot([x0, x1], [y0, y1], color="crimson" if colliding else "tab:blue",
                linewidth=1.6 if colliding else 0.8, zorder=3)
        if colliding:
            ax.plot((x0 + x1) / 2, (y0 + y1) / 2, marker="x", color="crimson", markersize=9, mew=2, zorder=5)
    entries = np.array([v["entry"] for v in visits])
    exits = np.array([v["exit"] for v in visits if v["exit"] is not None]).reshape(-1, 2)
    ax.scatter(entries[:, 0], entries[:, 1], s=9, color="red", zorder=4, label="entry points")
    ax.scatter(exits[:, 0], exits[:, 1], s=9, color="gold", edgecolors="0.3", linewidths=0.3, zorder=4,
               label="exit points")
    ax.set_title(f"{title}: {len(hits)} colliding transition(s)", fontsize=9)
    ax.set_xlim(0, sheet["width"])
    ax.set_ylim(0, sheet["height"])
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)


def sheet_figure(sheet: Mapping, records: Mapping[str, Mapping]) -> Figure:
    """Fig. 10's style: entry points red, exit points yellow, transitions blue, collisions red with a cross."""
    fig, axes = plt.subplots(1, len(records), figsize=(6.5 * len(records), 5.0), dpi=120, squeeze=False)
    for ax, (title, record) in zip(axes[0], records.items(), strict=True):
        _draw(ax, sheet, record, title)
    axes[0][0].legend(loc="upper right", fontsize=7)
    fig.tight_layout()
    return fig
