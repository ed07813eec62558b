"""MLflow wiring: one experiment, one parent run per pipeline run, one child run per stage item.

The store is SQLite in the repository root (``sqlite:///$DVC_ROOT/mlflow.db``) unless
``MLFLOW_TRACKING_URI`` is set; artefacts go to ``$DVC_ROOT/mlruns``.  The parent run is named
after the DVC experiment (``DVC_EXP_NAME``) or ``repro-<git sha>`` and found again by its
``pipeline_key`` tag, so every stage of one pipeline run lands under it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import subprocess
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

EXPERIMENT = "cnc-curvature"
log = logging.getLogger(__name__)


def repo_root() -> Path:
    return Path(os.environ.get("DVC_ROOT") or Path.cwd()).resolve()


def tracking_uri() -> str:
    return os.environ.get("MLFLOW_TRACKING_URI") or f"sqlite:///{repo_root() / 'mlflow.db'}"


def git_commit(root: Path | None = None) -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=root or repo_root(),
                             capture_output=True, text=True, check=True)
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "nogit"


def pipeline_key() -> str:
    return os.environ.get("DVC_EXP_NAME") or f"repro-{git_commit()}"


def _parent_run_id(client: Any, experiment_id: str, key: str) -> str:
    query = f"tags.pipeline_key = '{key}' and tags.pipeline_role = 'parent'"
    found = client.search_runs([experiment_id], filter_string=query, max_results=1)
    if found:
        return found[0].info.run_id
    tags = {"pipeline_key": key, "pipeline_role": "parent", "git_commit": git_commit()}
    run = client.create_run(experiment_id, run_name=key, tags=tags)
    client.set_terminated(run.info.run_id)
    return run.info.run_id


@contextlib.contextmanager
def stage_run(stage: str, params: Mapping[str, Any] | None = None, **tags: str) -> Iterator[Any]:
    """Open the child run of ``stage`` (e.g. ``label@gear``) under the pipeline's parent run.

    The run is marked FAILED if the body raises.  Params are logged once, as given.
    """
    import mlflow

    mlflow.set_tracking_uri(tracking_uri())
    client = mlflow.MlflowClient()
    experiment = client.get_experiment_by_name(EXPERIMENT)
    experiment_id = (experiment.experiment_id if experiment else
                     client.create_experiment(EXPERIMENT, artifact_location=(repo_root() / "mlruns").as_uri()))
    parent = _parent_run_id(client, experiment_id, pipeline_key())
    name = os.environ.get("DVC_STAGE") or stage
    run_tags = {"stage": stage, "git_commit": git_commit(), "pipeline_key": pipeline_key(), **tags}
    with mlflow.start_run(experiment_id=experiment_id, run_name=name, parent_run_id=parent, tags=run_tags) as run:
        if params:
            mlflow.log_params({k: str(v)[:6000] for k, v in params.items()})
        yield run
