"""Machining time of smoothed windows against their originals: the feedrate stage's summary."""

from __future__ import annotations

import numpy as np


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
