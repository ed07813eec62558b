"""Machining time of every window the optimize stage smoothed, and of its original (issue 9).
Run: python -m toolpath.stages.feedrate --shape gear

Each window is a G01 polyline: the planner of :mod:`toolpath.feedrate` runs it under the NURBS corner paper's limits
(Eq. 15-22) with the controller blend of ``feedrate.blend_tolerance`` at each vertex.  Writes
``<paths.metrics>/feedrate/<shape>.json`` (per fidelity mode, encoding and method: windows, mean
original and smoothed time, time saved, largest two-sided (Hausdorff) distance between a smoothed
window and its original, whether every plan kept its limits and lay between its bounds: deterministic) and
``<paths.metrics>/feedrate/<shape>.csv``
(one row per smoothed window).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from toolpath import config, tracking
from toolpath.feedrate.assess import assess
from toolpath.feedrate.limits import Machine, polyline_radius
from toolpath.geometry.hausdorff import hausdorff
from toolpath.shapes.synth import SHAPES
from toolpath.stages._common import (
    grouped_metrics,
    load_arrays,
    load_windows,
    progress,
    shape_arg,
    write_json,
    write_rows,
)

ROW_FIELDS = ("window", "mode", "encoding", "method", "time_original", "time_smoothed", "time_saved_pct",
              "hausdorff_mm", "within_limits", "bracketed")


def load_smoothed(path: Path) -> dict:
    return load_arrays(path, ("points", "window", "method", "mode", "encoding"), "smoothed-windows", "optimize")


def summarise(rows: list[dict]) -> dict:
    """Per mode, encoding and method: the means and the worst cases of the rows."""
    groups: dict = {}
    for r in rows:
        groups.setdefault(r["mode"], {}).setdefault(r["encoding"], {}).setdefault(r["method"], []).append(r)
    out: dict = {}
    for mode, by_encoding in groups.items():
        for encoding, by_method in by_encoding.items():
            for method, rs in by_method.items():
                original = float(np.sum([r["time_original"] for r in rs]))
                smoothed = float(np.sum([r["time_smoothed"] for r in rs]))
                out.setdefault(mode, {}).setdefault(encoding, {})[method] = {
                    "windows": len(rs),
                    "mean_time_original_s": original / len(rs),
                    "mean_time_smoothed_s": smoothed / len(rs),
                    "time_saved_pct": 100.0 * (1.0 - smoothed / original),  # of the total over the windows
                    "mean_window_time_saved_pct": float(np.mean([r["time_saved_pct"] for r in rs])),
                    "max_hausdorff_mm": float(np.max([r["hausdorff_mm"] for r in rs])),
                    "all_within_limits": all(r["within_limits"] for r in rs),
                    "all_bracketed": all(r["bracketed"] is not False for r in rs),
                }
    return out


def main(argv: list[str] | None = None) -> None:
    args = shape_arg(__doc__.split("\n")[0], argv, SHAPES)
    cfg = config.load()
    fcfg = OmegaConf.to_container(cfg.feedrate, resolve=True)
    machine = Machine(**fcfg["machine"])
    band = math.inf if fcfg["band"] is None else float(fcfg["band"])
    windows = load_windows(Path(cfg.paths.windows) / f"{args.shape}.npz")["windows"].astype(np.float64)
    smoothed = load_smoothed(Path(cfg.paths.smoothed) / f"{args.shape}.npz")

    def planned(points: np.ndarray) -> dict:
        return assess(points, polyline_radius(points, fcfg["blend_tolerance"]), machine, straight=True, band=band,
                      bounds=fcfg["bounds"])[1]

    with tracking.stage_run(f"feedrate@{args.shape}", {"seed": cfg.seed, **config.flat(fcfg, "feedrate")},
                            shape=args.shape):
        import mlflow

        originals = {int(w): planned(windows[int(w)]) for w in np.unique(smoothed["window"])}
        rows = []
        for k in progress(list(range(len(smoothed["window"]))), f"feedrate {args.shape}"):
            w = int(smoothed["window"][k])
            points = smoothed["points"][k].astype(np.float64)
            record, before = planned(points), originals[w]
            rows.append({"window": w, "mode": str(smoothed["mode"][k]), "encoding": str(smoothed["encoding"][k]),
                         "method": str(smoothed["method"][k]), "time_original": before["time"],
                         "time_smoothed": record["time"],
                         "time_saved_pct": 100.0 * (1.0 - record["time"] / before["time"]),
                         "hausdorff_mm": float(hausdorff(points, windows[w])),
                         "within_limits": record["within_limits"] and before["within_limits"],
                         "bracketed": None if not fcfg["bounds"] else record["bracketed"] and before["bracketed"]})
        summary = {"methods": summarise(rows), "windows": len(originals), "plans": len(rows) + len(originals)}
        metrics_dir = Path(cfg.paths.metrics) / "feedrate"
        write_json(summary, metrics_dir / f"{args.shape}.json")
        write_rows(rows, ROW_FIELDS, metrics_dir / f"{args.shape}.csv")
        mlflow.log_metrics(grouped_metrics(summary["methods"], {"time_saved_pct": "time_saved_pct",
                                                                "max_hausdorff_mm": "max_hausdorff_mm"}))
        mlflow.log_artifact(str(metrics_dir / f"{args.shape}.json"))
        mlflow.log_artifact(str(metrics_dir / f"{args.shape}.csv"))


if __name__ == "__main__":
    main()
