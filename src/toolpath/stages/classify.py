"""Table 5: every model's prediction for one drawn test window per category.  Run: python -m toolpath.stages.classify

Writes ``<paths.metrics>/classify.json``: the shape (``classify.shape``), each drawn window's points (mm)
and each model's predicted category, which the report turns into Table 5 and its figure.  The draw's seed
is derived from ``seed`` and the name "report" (the names are part of the result: see
:mod:`toolpath.pipeline.seeds`).
"""

from __future__ import annotations

from toolpath.models.training import examples
from toolpath.pipeline import artifacts, config, settings, tracking


def main(argv: list[str] | None = None) -> None:
    cfg = config.load()
    shape, layout = cfg.classify.shape, settings.layout(cfg)
    data = artifacts.load_windows(layout.windows_file(shape), shape)
    with tracking.stage_run("classify", {"seed": cfg.seed, "classify.shape": shape}, shape=shape):
        import mlflow

        drawn = examples.draw_per_category(data.windows, data.label, data.split == artifacts.Split.TEST,
                                           artifacts.CATEGORIES, config.seed_for(cfg.seed, "report"))
        predictors = {m: artifacts.load_classifier(layout.checkpoint(shape, m), f"train@{m}").predict
                      for m in cfg.train.models}
        predicted = examples.predictions(drawn, predictors)
        artifacts.write_json({"shape": shape, "windows": {str(c): w.tolist() for c, w in drawn.items()},
                              "predictions": {m: {str(c): p for c, p in by.items()} for m, by in predicted.items()}},
                             layout.classify_metrics)
        mlflow.log_metrics({f"classify.{m}.correct": sum(p == c for c, p in by.items())
                            for m, by in predicted.items()})


if __name__ == "__main__":
    main()
