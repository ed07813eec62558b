"""The report: Li et al.'s Tables 1-6 and Figures 6-11 beside ours, then Xie & Zhu's and the NURBS corner
paper's results (our Tables 7-15, Figures 12-17).  Run: python -m toolpath.stages.report

Reads only DVC outputs and writes ``<paths.report>/report.md``, ``tables/table<N>_<name>.{md,tex}``,
``figures/fig<N>_<name>.{png,pdf}`` and ``readme_block.md`` (the headline figure and the Table 3 /
Table 6 summaries; ``make readme`` puts it into README.md).  Sections are built by
:class:`toolpath.reports.builder.Report`.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import yaml

from toolpath.pipeline import config, settings, tracking
from toolpath.reports import summary
from toolpath.reports.builder import Report
from toolpath.reports.document import report_markdown
from toolpath.reports.headline import headline

BLOCK_FILE = "readme_block.md"


def source_state() -> tuple[str, bool | None]:
    """The git commit and whether the source (``src``, ``conf``, ``dvc.yaml``) has uncommitted changes
    (None when git cannot tell)."""
    try:
        out = subprocess.run(["git", "status", "--porcelain", "--", "src", "conf", "dvc.yaml"], capture_output=True,
                             text=True, check=True)
        return tracking.git_commit(), not out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return tracking.git_commit(), None


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    out = Path(cfg.paths.report)
    with tracking.stage_run("report", config.flat(cfg.report, "report")):
        import mlflow

        report = Report(cfg, settings.layout(cfg), out,  # builds every table and figure
                        training=lambda shape, model: settings.training(cfg, shape, model)[1])
        sections = report.sections()
        commit, clean = source_state()
        (out / "report.md").write_text(report_markdown(sections, cfg.profile, commit, clean), encoding="utf-8")
        (out / BLOCK_FILE).write_text(summary.readme_block(report.summaries, cfg.profile, commit, out) + "\n",
                                      encoding="utf-8")
        layout = settings.layout(cfg)
        anchors = [m for m in cfg.train.models if cfg.models[m]["_target_"] == "toolpath.models.MCRL"]
        tracking.log_to_parent(*headline(layout, cfg.shapes, cfg.train.models, anchors))
        tracking.log_to_parent_artifacts({"": out / "report.md", "tables": out / "tables",
                                          "figures": out / "figures" / f"{summary.HEADLINE}.png"})
        if (pipeline := Path("dvc.yaml")).is_file():  # the stages DVC skipped: say which run made their outputs
            tracking.record_up_to_date(set(yaml.safe_load(pipeline.read_text(encoding="utf-8"))["stages"]))
        missing = [s.title for s in sections if s.missing]
        mlflow.log_metrics({"sections": len(sections), "missing_sections": len(missing)})
        mlflow.log_artifact(str(out / "report.md"))
        for path in report.written:
            mlflow.log_artifact(str(path), artifact_path=path.parent.name)
        if missing:
            print("report: missing sections: " + "; ".join(missing))


if __name__ == "__main__":
    main()
