"""Window and label one shape's programs (Algorithm 1).  Run: python -m toolpath.stages.label --shape gear

Writes ``<paths.windows>/<shape>.npz`` (windows, origin, local_curvature, label, program,
first_line, split, plus the program file names) and ``<paths.metrics>/label/<shape>.json``
(class counts and shares, LocalCurvature quantiles, windows per split).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from toolpath import config, tracking
from toolpath.gcode import GCodeError, ReaderOptions, read_file
from toolpath.labels import CATEGORY_NAMES, SPLIT_NAMES, concat, label_program, split_by_program
from toolpath.shapes.synth import SHAPES
from toolpath.stages._common import progress, shape_arg, write_json


def summary(windows, program: np.ndarray, split: np.ndarray, n_programs: int) -> dict:
    """Metrics of one shape's labelled windows (keys are stable: DVC and MLflow use them)."""
    counts = np.bincount(windows.label, minlength=5)[1:]
    total = max(int(counts.sum()), 1)
    quantiles = np.quantile(windows.local_curvature, [0.05, 0.25, 0.5, 0.75, 0.95]) if len(windows) else [np.nan] * 5
    return {
        "programs": n_programs,
        "windows": int(len(windows)),
        "unlabelled_points": int(windows.unlabelled_points),
        "class_count": {str(c + 1): int(n) for c, n in enumerate(counts)},
        "class_share": {str(c + 1): round(float(n) / total, 6) for c, n in enumerate(counts)},
        "class_name": {str(c + 1): name for c, name in enumerate(CATEGORY_NAMES)},
        "local_curvature": {f"q{int(q * 100):02d}": round(float(v), 6)
                            for q, v in zip((0.05, 0.25, 0.5, 0.75, 0.95), quantiles, strict=True)},
        "split_windows": {name: int((split == k).sum()) for k, name in enumerate(SPLIT_NAMES)},
        "split_programs": {name: int(len(np.unique(program[split == k]))) for k, name in enumerate(SPLIT_NAMES)},
    }


def main(argv: list[str] | None = None) -> None:
    args = shape_arg(__doc__.split("\n")[0], argv, SHAPES)
    cfg = config.load()
    lab, read_opts = cfg.label, ReaderOptions(**cfg.gcode.read)
    files = sorted((Path(cfg.paths.gcode) / args.shape).glob("*.nc"))
    if not files:
        sys.exit(f"no G-code in {Path(cfg.paths.gcode) / args.shape}: run the generate stage first")
    params = {"shape": args.shape, "seed": cfg.seed, **config.flat(lab, "label"), **config.flat(cfg.gcode.read, "read")}
    with tracking.stage_run(f"label@{args.shape}", params):
        import mlflow

        parts, program = [], []
        for k, path in enumerate(progress(files, f"label {args.shape}")):
            try:
                windows = label_program(read_file(path, read_opts), lab.window, lab.stride)
            except GCodeError as exc:
                sys.exit(str(exc))
            parts.append(windows)
            program.append(np.full(len(windows), k, dtype=np.int32))
        windows, program = concat(parts, lab.window), np.concatenate(program)
        fractions = (lab.split.train, lab.split.val, lab.split.test)
        split = split_by_program(program, windows.label, fractions, config.seed_for(cfg.seed, "label", args.shape))
        out = Path(cfg.paths.windows) / f"{args.shape}.npz"
        out.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(out, windows=windows.windows, origin=windows.origin,
                            local_curvature=windows.local_curvature, label=windows.label, program=program,
                            first_line=windows.first_line, split=split,
                            program_files=np.array([p.name for p in files]))
        metrics = summary(windows, program, split, len(files))
        write_json(metrics, Path(cfg.paths.metrics) / "label" / f"{args.shape}.json")
        mlflow.log_metrics({f"label/{k}": v for k, v in config.flat(metrics).items() if isinstance(v, int | float)})


if __name__ == "__main__":
    main()
