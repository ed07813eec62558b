"""Synthesise one shape's rough CAM programs as G-code, then read them back as a control would and cut them
into labelled windows (Algorithm 1).  Run: python -m toolpath.stages.generate --shape gear

Writes ``<paths.gcode>/<shape>/<shape>_<k>.nc`` (each program's header records every value drawn for it, so a
file explains itself), the shape's windows file (:class:`toolpath.pipeline.artifacts.WindowSet`) and its label
metrics (class counts and shares, LocalCurvature quantiles, windows per split).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from toolpath.gcode import GCodeError, read_file
from toolpath.gcode.writer import write_program
from toolpath.geometry.labels import concat, label_program, split_by_program
from toolpath.geometry.labels.summary import label_summary
from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.workers import clean_dir, pool_map, progress, shape_arg
from toolpath.shapes.synth import synthesize


def write_programs(cfg, shape: str, out: Path) -> dict:
    """The shape's programs, each drawn from the seed's stream in turn; their count and points."""
    synth = OmegaConf.to_container(cfg.generate, resolve=True)
    shape_cfg = synth[shape]
    roughness = {**synth["roughness"], **shape_cfg["roughness"]}
    rng = np.random.default_rng(config.seed_for(cfg.seed, "generate", shape))
    points = 0
    for k in progress(list(range(shape_cfg["programs"])), f"generate {shape}"):
        passes, drawn = synthesize(shape, shape_cfg["part"], synth["cam"], roughness, rng)
        spec = settings.program_spec(cfg, stay_down=bool(rng.random() < drawn.pop("cam.stay_down")))
        header = f"{shape} {k} seed {cfg.seed}: " + ", ".join(f"{key}={value:.6g}" for key, value in drawn.items())
        (out / f"{shape}_{k:03d}.nc").write_text(write_program(passes, spec, header), encoding="utf-8")
        points += sum(len(p.xy) for p in passes)
    return {"generate.programs": shape_cfg["programs"], "generate.points": points}


def _label_file(job: tuple) -> object:
    """One program's labelled windows, or its reader error as text (a GCodeError does not pickle)."""
    path, read_opts, window, stride, bounds = job
    try:
        return label_program(read_file(path, read_opts), window, stride, bounds)
    except GCodeError as exc:
        return str(exc)


def label_programs(cfg, shape: str, files: list[Path]) -> dict:
    """Window and label the programs, split them by program, write the windows file and the label metrics."""
    lab, layout, read_opts = cfg.label, settings.layout(cfg), settings.reader_options(cfg)
    jobs = [(path, read_opts, lab.window, lab.stride, settings.bounds(cfg)) for path in files]
    parts = pool_map(_label_file, jobs, settings.workers(cfg, "label"), f"label {shape}")
    for failure in (p for p in parts if isinstance(p, str)):
        sys.exit(failure)
    program = [np.full(len(windows), k, dtype=np.int32) for k, windows in enumerate(parts)]
    windows, program = concat(parts, lab.window), np.concatenate(program)
    fractions = (lab.split.train, lab.split.val, lab.split.test)
    split = split_by_program(program, windows.label, fractions, config.seed_for(cfg.seed, "label", shape))
    artifacts.save_windows(artifacts.WindowSet(
        windows=windows.windows, origin=windows.origin, local_curvature=windows.local_curvature,
        label=windows.label, program=program, first_line=windows.first_line, split=split,
        program_files=np.array([p.name for p in files])), layout.windows_file(shape))
    metrics = label_summary(windows, program, split, len(files))
    artifacts.write_json(metrics, layout.label_metrics(shape))
    return {f"label.{k}": v for k, v in config.flat(metrics).items() if isinstance(v, int | float)}


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    args = shape_arg(__doc__.split("\n")[0], argv, cfg.shapes)
    synth = OmegaConf.to_container(cfg.generate, resolve=True)
    params = {"shape": args.shape, "seed": cfg.seed, **config.flat(synth["cam"], "cam"),
              **config.flat({**synth["roughness"], **synth[args.shape]["roughness"]}, "roughness"),
              **config.flat(synth[args.shape], args.shape), **config.flat(cfg.label, "label"),
              **config.flat(cfg.gcode.read, "read")}
    with tracking.stage_run(f"generate@{args.shape}", params):
        import mlflow

        out = clean_dir(settings.layout(cfg).programs(args.shape))
        mlflow.log_metrics(write_programs(cfg, args.shape, out))
        mlflow.log_metrics(label_programs(cfg, args.shape, sorted(out.glob("*.nc"))))


if __name__ == "__main__":
    main()
