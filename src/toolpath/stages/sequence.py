"""Lay out Xie & Zhu's sheets of many parts and sequence each by their S-shaped algorithm and the baselines.
Run: python -m toolpath.stages.sequence

Writes ``<paths.sheets>/sheet_<n>.json`` per part count of ``sheets.counts`` (the sheet size and every part's
kind and contour, mm; the plans are made on the sheet as read back from that file); per sheet the S-shaped plan
with collision avoidance as one continuous-cut program and every method's visits and collisions (for the
report's figure); the metrics (empty travel, collisions, optimisation rate against the manual order:
deterministic) and the timing (each method's planning time, Table 1's Time column), at the paths of
:class:`toolpath.pipeline.artifacts.Layout`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.artifacts import write_json
from toolpath.pipeline.workers import clean_dir, pool_map, progress
from toolpath.shapes.sequencing import Sheet, make_sheet, part_tree, run_sheet, s_shaped, score, sheet_program
from toolpath.shapes.sequencing.experiment import outcome_records, plan_record


def load_sheet(path: Path) -> Sheet:
    try:
        return Sheet.from_dict(artifacts.read_json(path, "sequence"))
    except (ValueError, KeyError, TypeError) as exc:
        raise artifacts.ArtifactError(path, f"not a readable sheet ({exc})", "sequence") from None


def lay_out(sc: dict, seed: int, layout: artifacts.Layout) -> None:
    """Every sheet of ``sc["counts"]`` (conf/sheets), written as JSON; its sizes logged."""
    import mlflow

    clean_dir(layout.sheets)
    for n in progress(list(sc["counts"]), "sheets"):
        try:
            sheet = make_sheet(int(n), sc["width"], sc["height"], sc["kinds"], sc["size"], sc["gap"], sc["margin"],
                               sc["simplify"], np.random.default_rng(config.seed_for(seed, "sheets", str(n))),
                               sc["attempts"])
        except ValueError as exc:
            raise SystemExit(f"params.yaml (conf/sheets): the sheet of {n} parts: {exc}") from None
        write_json(sheet.to_dict(), layout.sheet(int(n)))
        mlflow.log_metrics({f"sheets.{n}.vertices": sum(len(p.ring) for p in sheet.parts),
                            f"sheets.{n}.contour_mm": sum(p.perimeter for p in sheet.parts)})


def _run_sheet(job: tuple) -> dict:
    sheet, seq = job
    return run_sheet(sheet, seq["algorithm"], seq["gtsp"], seq["feed"], seq["methods"])


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    seq, sc = OmegaConf.to_container(cfg.sequence, resolve=True), OmegaConf.to_container(cfg.sheets, resolve=True)
    counts, layout, spec = [int(n) for n in sc["counts"]], settings.layout(cfg), settings.program_spec(cfg)
    metrics: dict = {"sheets": {}, "expansion": {}}
    seconds: dict = {}
    params = {"seed": cfg.seed, **config.flat(sc, "sheets"), **config.flat(seq, "sequence")}
    with tracking.stage_run("sequence", params):
        import mlflow

        lay_out(sc, cfg.seed, layout)
        sheets = {n: load_sheet(layout.sheet(n)) for n in counts}
        out = clean_dir(layout.sequence)
        # sheets are independent: one per worker (each method's seconds are then timed beside another sheet's work)
        planned = pool_map(_run_sheet, [(sheets[n], seq) for n in counts], settings.workers(cfg, "sequence"),
                           "sequence sheets")
        for n, outcomes in zip(counts, planned, strict=True):
            metrics["sheets"][str(n)], seconds[str(n)] = outcome_records(outcomes)
            write_json({m: plan_record(o.plan, sheets[n]) for m, o in outcomes.items()}, layout.sheet_plans(n))
            if "s_shaped" in outcomes:
                title = f"Xie & Zhu S-shaped sequencing, {n} parts, seed {cfg.seed}, continuous cut"
                layout.sheet_program(n).write_text(
                    sheet_program(outcomes["s_shaped"].plan, sheets[n].parts, spec, seq["depth"], title), "utf-8")
        study = seq["expansion_study"]
        if study["sheet"] not in sheets:
            raise SystemExit(f"params.yaml: sequence.expansion_study.sheet {study['sheet']} is not in sheets.counts")
        sheet, tree = sheets[study["sheet"]], part_tree(sheets[study["sheet"]].parts)
        for count in study["counts"]:
            plan, _ = s_shaped(sheet, count, seq["algorithm"]["start_up"], True, seq["algorithm"]["max_handling"], tree)
            metrics["expansion"][str(count)] = score(plan, sheet.parts, tree, seq["feed"])
        write_json(metrics, layout.sequence_metrics)
        write_json(seconds, layout.sequence_timing)
        mlflow.log_metrics({f"sequence.{n}.{m}.{k}": float(v) for n, row in metrics["sheets"].items()
                            for m, scores in row.items() for k, v in scores.items()
                            if isinstance(v, int | float) and not isinstance(v, bool)})
        mlflow.log_metrics({f"sequence.expansion.{c}.{k}": float(v) for c, s in metrics["expansion"].items()
                            for k, v in s.items()})
        mlflow.log_artifacts(str(out), artifact_path="sequence")


if __name__ == "__main__":
    main()
