"""The wiring of the DVC pipeline, shared by every stage module: the files passed between stages
(:mod:`~toolpath.pipeline.artifacts`), ``conf/`` composed into ``params.yaml`` (:mod:`~toolpath.pipeline.config`,
:mod:`~toolpath.pipeline.schema`), settings objects built from it (:mod:`~toolpath.pipeline.settings`),
seeds (:mod:`~toolpath.pipeline.seeds`), MLflow (:mod:`~toolpath.pipeline.tracking`), worker pools
(:mod:`~toolpath.pipeline.workers`) and the stage timer of ``make repro`` (:mod:`~toolpath.pipeline.stage_times`).

Domain packages never import it, except :mod:`~toolpath.pipeline.seeds` (a pure function); Hydra, DVC and
MLflow are imported here and in ``toolpath.stages`` / ``toolpath.sweep`` only."""
