"""Lay out Xie & Zhu's sheets of many parts.  Run: python -m toolpath.stages.sheets

Writes ``<paths.sheets>/sheet_<n>.json`` per part count of ``sheets.counts``: the sheet size and
every part's kind and contour (mm), the data the ``sequence`` stage reads.
"""

from __future__ import annotations

import numpy as np
from omegaconf import OmegaConf

from toolpath.pipeline import config, settings, tracking
from toolpath.pipeline.artifacts import write_json
from toolpath.pipeline.workers import clean_dir, progress
from toolpath.sequencing.sheets import make_sheet


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    sc = OmegaConf.to_container(cfg.sheets, resolve=True)
    layout = settings.layout(cfg)
    clean_dir(layout.sheets)
    with tracking.stage_run("sheets", {"seed": cfg.seed, **config.flat(sc, "sheets")}):
        import mlflow

        for n in progress(list(sc["counts"]), "sheets"):
            rng = np.random.default_rng(config.seed_for(cfg.seed, "sheets", str(n)))
            try:
                sheet = make_sheet(int(n), sc["width"], sc["height"], sc["kinds"], sc["size"], sc["gap"],
                                   sc["margin"], sc["simplify"], rng, sc["attempts"])
            except ValueError as exc:
                raise SystemExit(f"params.yaml (conf/sheets): the sheet of {n} parts: {exc}") from None
            write_json(sheet.to_dict(), layout.sheet(int(n)))
            mlflow.log_metrics({f"sheets.{n}.vertices": sum(len(p.ring) for p in sheet.parts),
                                f"sheets.{n}.contour_mm": sum(p.perimeter for p in sheet.parts)})


if __name__ == "__main__":
    main()
