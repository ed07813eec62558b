"""Window and label one shape's programs (Algorithm 1).  Run: python -m toolpath.stages.label --shape gear

Writes the shape's windows file (:class:`toolpath.pipeline.artifacts.WindowSet`) and its label metrics (class
counts and shares, LocalCurvature quantiles, windows per split).
"""

from __future__ import annotations

import sys

import numpy as np

from toolpath.gcode import GCodeError, read_file
from toolpath.labels import concat, label_program, split_by_program
from toolpath.labels.summary import label_summary
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import pool_map, shape_arg


def _label_file(job: tuple) -> object:
    """One program's labelled windows, or its reader error as text (a GCodeError does not pickle)."""
    path, read_opts, window, stride, bounds = job
    try:
        return label_program(read_file(path, read_opts), window, stride, bounds)
    except GCodeError as exc:
        return str(exc)


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    args = shape_arg(__doc__.split("\n")[0], argv, cfg.shapes)
    lab, layout, read_opts = cfg.label, settings.layout(cfg), settings.reader_options(cfg)
    files = sorted(layout.programs(args.shape).glob("*.nc"))
    if not files:
        sys.exit(f"no G-code in {layout.programs(args.shape)}: run `dvc repro generate@{args.shape}` first")
    params = {"shape": args.shape, "seed": cfg.seed, **config.flat(lab, "label"), **config.flat(cfg.gcode.read, "read")}
    with tracking.stage_run(f"label@{args.shape}", params):
        import mlflow

        jobs = [(path, read_opts, lab.window, lab.stride, settings.bounds(cfg)) for path in files]
        parts = pool_map(_label_file, jobs, lab.workers, f"label {args.shape}")
        for failure in (p for p in parts if isinstance(p, str)):
            sys.exit(failure)
        program = [np.full(len(windows), k, dtype=np.int32) for k, windows in enumerate(parts)]
        windows, program = concat(parts, lab.window), np.concatenate(program)
        fractions = (lab.split.train, lab.split.val, lab.split.test)
        split = split_by_program(program, windows.label, fractions, config.seed_for(cfg.seed, "label", args.shape))
        artifacts.save_windows(artifacts.WindowSet(
            windows=windows.windows, origin=windows.origin, local_curvature=windows.local_curvature,
            label=windows.label, program=program, first_line=windows.first_line, split=split,
            program_files=np.array([p.name for p in files])), layout.windows_file(args.shape))
        metrics = label_summary(windows, program, split, len(files))
        artifacts.write_json(metrics, layout.label_metrics(args.shape))
        mlflow.log_metrics({f"label.{k}": v for k, v in config.flat(metrics).items() if isinstance(v, int | float)})


if __name__ == "__main__":
    main()
