"""Sequence every sheet by Xie & Zhu's S-shaped algorithm and the baselines.  Run: python -m toolpath.stages.sequence

Reads every sheet; writes per sheet the S-shaped plan with collision avoidance as one continuous-cut
program and every method's visits and collisions (for the report's figure), the metrics (empty travel,
collisions, optimisation rate against the manual order: deterministic) and the timing (each method's
planning time, Table 1's Time column), at the paths of :class:`toolpath.pipeline.artifacts.Layout`.
"""

from __future__ import annotations

from pathlib import Path

from omegaconf import OmegaConf

from toolpath.pipeline import artifacts, config, settings, tracking
from toolpath.pipeline.artifacts import write_json
from toolpath.pipeline.workers import clean_dir, pool_map
from toolpath.sequencing import Sheet, part_tree, run_sheet, s_shaped, score, sheet_program
from toolpath.sequencing.planner import SheetPlan
from toolpath.sequencing.score import collisions


def load_sheet(path: Path) -> Sheet:
    try:
        return Sheet.from_dict(artifacts.read_json(path, "sheets"))
    except (ValueError, KeyError, TypeError) as exc:
        raise artifacts.ArtifactError(path, f"not a readable sheet ({exc})", "sheets") from None


def plan_record(plan: SheetPlan, sheet: Sheet) -> dict:
    """Visits and collisions of a plan, as JSON (mm, 4 decimals)."""
    def xy(p):
        return None if p is None else [round(float(p[0]), 4), round(float(p[1]), 4)]
    return {"visits": [{"part": v.part, "full": v.full, "entry": xy(v.entry_xy), "exit": xy(v.exit_xy)}
                       for v in plan.visits],
            "collisions": [list(c) for c in collisions(plan, sheet.parts, part_tree(sheet.parts))]}


def _run_sheet(job: tuple) -> dict:
    sheet, seq = job
    return run_sheet(sheet, seq["algorithm"], seq["gtsp"], seq["feed"], seq["methods"])


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    seq = OmegaConf.to_container(cfg.sequence, resolve=True)
    counts = [int(n) for n in cfg.sheets.counts]
    layout = settings.layout(cfg)
    sheets = {n: load_sheet(layout.sheet(n)) for n in counts}
    out = clean_dir(layout.sequence)
    spec = settings.program_spec(cfg)
    metrics: dict = {"sheets": {}, "expansion": {}}
    seconds: dict = {}
    with tracking.stage_run("sequence", {"seed": cfg.seed, **config.flat(seq, "sequence")}):
        import mlflow

        # sheets are independent: one per worker (each method's seconds are then timed beside another sheet's work)
        planned = pool_map(_run_sheet, [(sheets[n], seq) for n in counts], seq["workers"], "sequence sheets")
        for n, outcomes in zip(counts, planned, strict=True):
            sheet = sheets[n]
            manual = outcomes["manual"].scores["empty_travel_mm"] if "manual" in outcomes else None
            metrics["sheets"][str(n)] = {
                m: {**o.scores, **{k: v for k, v in o.facts.items() if k not in ("seconds", "time_capped")},
                    "optimisation_rate_pct": None if manual is None
                    else 100.0 * (1 - o.scores["empty_travel_mm"] / manual)}
                for m, o in outcomes.items()}
            seconds[str(n)] = {m: {"seconds": o.seconds, "time_capped": bool(o.facts.get("time_capped", False))}
                               for m, o in outcomes.items()}
            write_json({m: plan_record(o.plan, sheet) for m, o in outcomes.items()}, layout.sheet_plans(n))
            if "s_shaped" in outcomes:
                title = f"Xie & Zhu S-shaped sequencing, {n} parts, seed {cfg.seed}, continuous cut"
                layout.sheet_program(n).write_text(
                    sheet_program(outcomes["s_shaped"].plan, sheet.parts, spec, seq["depth"], title), encoding="utf-8")
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
