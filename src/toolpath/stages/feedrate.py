"""Machining time of every window the optimize stage smoothed, and of its original.
Run: python -m toolpath.stages.feedrate --shape gear

Each window is a G01 polyline: the planner of :mod:`toolpath.feedrate` runs it under the NURBS corner
paper's limits (Eq. 15-22) with the controller blend of ``feedrate.blend_tolerance`` at each vertex.
Writes the summary (per fidelity mode, encoding and method: windows, mean original and smoothed time,
time saved, the largest two-sided distance between a smoothed window and its original, whether every
plan kept its limits and lay between its bounds, computed for every ``feedrate.bounds_every``-th plan:
deterministic) and one row per smoothed window.
"""

from __future__ import annotations

import numpy as np

from toolpath.feedrate.assess import assess
from toolpath.feedrate.limits import polyline_radius
from toolpath.feedrate.windows import summarise
from toolpath.geometry.hausdorff import hausdorff
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import grouped_metrics, pool_map, shape_arg

ROW_FIELDS = ("window", "mode", "encoding", "method", "time_original", "time_smoothed", "time_saved_pct",
              "hausdorff_mm", "within_limits", "bracketed")


def _plan(job: tuple) -> list[dict]:
    """The planner's record of each polyline of one chunk (with its bounds where ``checks`` says)."""
    polylines, checks, machine, blend_tolerance, band = job
    return [assess(points, polyline_radius(points, blend_tolerance), machine, straight=True, band=band,
                   bounds=check)[1] for points, check in zip(polylines, checks, strict=True)]


def _bracketed(*records: dict) -> bool | None:
    """Whether every record whose bounds were computed lay between them (None: no bound computed)."""
    flags = [r["bracketed"] for r in records if "bracketed" in r]
    return all(flags) if flags else None


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    args = shape_arg(__doc__.split("\n")[0], argv, cfg.shapes)
    fcfg, layout = settings.plain(cfg.feedrate), settings.layout(cfg)
    machine, band = settings.machine(cfg), settings.feed_band(cfg)
    windows = artifacts.load_windows(layout.windows_file(args.shape), args.shape).windows.astype(np.float64)
    smoothed = artifacts.load_smoothed(layout.smoothed_file(args.shape), args.shape)

    with tracking.stage_run(f"feedrate@{args.shape}", {"seed": cfg.seed, **config.flat(fcfg, "feedrate")},
                            shape=args.shape):
        import mlflow

        originals = [int(w) for w in np.unique(smoothed.window)]
        polylines = [windows[w] for w in originals] + [p.astype(np.float64) for p in smoothed.points]
        # chunks of plans, a few per worker: the plans are independent and take 10-100 ms each
        chunks = np.array_split(np.arange(len(polylines)), 8 * settings.workers(cfg, "feedrate"))
        # the bounds (toppra's above all) cost 5x the plan: a check on every `bounds_every`-th plan
        checks = [bool(fcfg["bounds"]) and i % fcfg["bounds_every"] == 0 for i in range(len(polylines))]
        jobs = [([polylines[i] for i in chunk], [checks[i] for i in chunk], machine, fcfg["blend_tolerance"], band)
                for chunk in chunks if len(chunk)]
        plans = [record for chunk in pool_map(_plan, jobs, settings.workers(cfg, "feedrate"), f"feedrate {args.shape}")
                 for record in chunk]
        before_of = dict(zip(originals, plans[: len(originals)], strict=True))
        rows = []
        for k, record in enumerate(plans[len(originals):]):
            w, points = int(smoothed.window[k]), polylines[len(originals) + k]
            before = before_of[w]
            rows.append({"window": w, "mode": str(smoothed.mode[k]), "encoding": str(smoothed.encoding[k]),
                         "method": str(smoothed.method[k]), "time_original": before["time"],
                         "time_smoothed": record["time"],
                         "time_saved_pct": 100.0 * (1.0 - record["time"] / before["time"]),
                         "hausdorff_mm": float(hausdorff(points, windows[w])),
                         "within_limits": record["within_limits"] and before["within_limits"],
                         "bracketed": _bracketed(record, before)})
        summary = {"methods": summarise(rows), "windows": len(originals), "plans": len(rows) + len(originals),
                   "plans_with_bounds": sum(checks)}
        artifacts.write_json(summary, layout.feedrate_summary(args.shape))
        artifacts.write_rows(rows, ROW_FIELDS, layout.feedrate_rows(args.shape))
        mlflow.log_metrics(grouped_metrics(summary["methods"], {"time_saved_pct": "time_saved_pct",
                                                                "max_hausdorff_mm": "max_hausdorff_mm"}))
        mlflow.log_artifact(str(layout.feedrate_summary(args.shape)))
        mlflow.log_artifact(str(layout.feedrate_rows(args.shape)))


if __name__ == "__main__":
    main()
