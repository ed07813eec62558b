"""Synthesise one shape's rough CAM programs as G-code.  Run: python -m toolpath.stages.generate --shape gear

Writes ``<paths.gcode>/<shape>/<shape>_<k>.nc``; each program's header records every value drawn
for it, so a file explains itself.
"""

from __future__ import annotations

import numpy as np
from omegaconf import OmegaConf

from toolpath.gcode.writer import write_program
from toolpath.pipeline import config, settings, tracking
from toolpath.pipeline.workers import clean_dir, progress, shape_arg
from toolpath.shapes.synth import synthesize


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    args = shape_arg(__doc__.split("\n")[0], argv, cfg.shapes)
    synth = OmegaConf.to_container(cfg.generate, resolve=True)
    shape_cfg = synth[args.shape]
    roughness = {**synth["roughness"], **shape_cfg["roughness"]}
    rng = np.random.default_rng(config.seed_for(cfg.seed, "generate", args.shape))
    out = clean_dir(settings.layout(cfg).programs(args.shape))
    params = {"shape": args.shape, "seed": cfg.seed, **config.flat(synth["cam"], "cam"),
              **config.flat(roughness, "roughness"), **config.flat(shape_cfg, args.shape)}
    with tracking.stage_run(f"generate@{args.shape}", params) as _:
        import mlflow

        points = 0
        for k in progress(list(range(shape_cfg["programs"])), f"generate {args.shape}"):
            passes, drawn = synthesize(args.shape, shape_cfg["part"], synth["cam"], roughness, rng)
            spec = settings.program_spec(cfg, stay_down=bool(rng.random() < drawn.pop("cam.stay_down")))
            header = f"{args.shape} {k} seed {cfg.seed}: " + ", ".join(
                f"{key}={value:.6g}" for key, value in drawn.items())
            (out / f"{args.shape}_{k:03d}.nc").write_text(write_program(passes, spec, header), encoding="utf-8")
            points += sum(len(p.xy) for p in passes)
        mlflow.log_metrics({"generate.programs": shape_cfg["programs"], "generate.points": points})


if __name__ == "__main__":
    main()
