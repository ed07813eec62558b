"""Each shape's best model in the MLflow model registry (``models:/toolpath-<shape>@best``)."""

from __future__ import annotations

from toolpath.pipeline.tracking import client, experiment_id, pipeline_key, with_retry


def registered_name(shape: str) -> str:
    return f"toolpath-{shape.replace('_', '-')}"


def latest_model_uri(shape: str, model: str) -> str | None:
    """The logged network of the newest finished ``train@<model>`` run of ``shape``, of this pipeline run when
    it trained the model (a queue runs several at once), else of the one whose outputs DVC kept (None: no
    network logged, e.g. the rule)."""
    import mlflow

    store = client()
    experiment = experiment_id(store)
    runs = store.search_runs([experiment], filter_string=f"tags.shape = '{shape}' AND tags.model = '{model}' AND "
                             "attributes.status = 'FINISHED'", order_by=["attributes.start_time DESC"], max_results=20)
    runs = sorted((r for r in runs if r.data.tags.get("stage") == f"train@{model}"),
                  key=lambda r: r.data.tags.get("pipeline_key") != pipeline_key())  # stable: newest first within
    for run in runs:
        logged = mlflow.search_logged_models(experiment_ids=[experiment], output_format="list",
                                             filter_string=f"source_run_id = '{run.info.run_id}'")
        if logged:
            return logged[0].model_uri
        return None
    return None


def register_best(shape: str, model_uri: str, model: str) -> None:
    """Register the shape's best model (one definition: :func:`toolpath.models.training.replicates.best_learned`)
    as ``toolpath-<shape>`` with the alias ``best``: ``models:/toolpath-<shape>@best``."""
    import mlflow

    name = registered_name(shape)
    store = mlflow.MlflowClient()
    version = with_retry(lambda: mlflow.register_model(model_uri, name, tags={"model": model, "shape": shape}))
    with_retry(lambda: store.set_registered_model_alias(name, "best", version.version))
