"""What a finished sweep leaves: the best trial tagged in MLflow, the tuned model config, the figures
and a summary JSON.  Idempotent, so every worker machine may run it when its trials are done."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import optuna
from omegaconf import OmegaConf

from toolpath.models.registry import split_schedule
from toolpath.sweep.study import PARENT_ATTR, SweepSpec, base_config, mlflow_client

COMPLETE = optuna.trial.TrialState.COMPLETE


def default_trial(study: optuna.Study) -> optuna.trial.FrozenTrial | None:
    found = [t for t in study.get_trials(states=(COMPLETE,)) if t.user_attrs.get("default_config")]
    return found[0] if found else None


def tag_best(spec: SweepSpec, study: optuna.Study) -> None:
    """``best_trial=true`` on the best trial's MLflow run (false on the others); the parent gets the figures."""
    client = mlflow_client(spec)
    best = study.best_trial
    for trial in study.get_trials(states=(COMPLETE,)):
        run_id = trial.user_attrs.get("mlflow_run_id")
        if run_id:
            client.set_tag(run_id, "best_trial", str(trial.number == best.number).lower())
    parent = study.user_attrs[PARENT_ATTR]
    client.set_tag(parent, "best_trial_number", str(best.number))
    client.set_tag(parent, "best_params", json.dumps(best.params, sort_keys=True))
    client.log_metric(parent, "best_value", float(best.value))
    default = default_trial(study)
    if default is not None:
        client.log_metric(parent, "default_value", float(default.value))
    client.log_metric(parent, "complete_trials", len(study.get_trials(states=(COMPLETE,))))
    client.set_terminated(parent)


def tuned_config(spec: SweepSpec, study: optuna.Study) -> Path:
    """Write the best trial as ``conf/model/<model>_tuned.yaml``: the model's keys, and the training
    keys of ``train.per_shape.<shape>`` and ``train.common`` (lr, epochs, clipping, ...) under ``schedule``,
    which the train stage applies to this model only, on every shape.  Keys outside both are listed in
    the header, not silently dropped."""
    from toolpath.sweep.space import overrides

    best = study.best_trial
    base = base_config(spec.root, spec.base_overrides)
    tuned = OmegaConf.create(OmegaConf.to_container(base.models[spec.model], resolve=True))
    network, schedule = split_schedule(OmegaConf.to_container(tuned))
    tuned = OmegaConf.create(network)
    values = {p.name: p.value(best.params[p.name]) for p in spec.params}
    elsewhere = []
    for p, text in zip(spec.params, overrides(list(spec.params), values), strict=True):
        model_prefix, train_prefixes = f"models.{spec.model}.", (f"train.per_shape.{spec.shape}.", "train.common.")
        if p.key.startswith(model_prefix):
            OmegaConf.update(tuned, p.key[len(model_prefix):], values[p.name], merge=False)
        elif train_prefix := next((t for t in train_prefixes if p.key.startswith(t)), None):
            schedule[p.key[len(train_prefix):]] = values[p.name]
        else:
            elsewhere.append(text)
    body = OmegaConf.to_container(tuned)
    if schedule:
        body["schedule"] = schedule
    default = default_trial(study)
    lines = [f"# Written by `python -m toolpath.sweep`: study {spec.study}, trial {best.number},",
             f"# {spec.objective} {best.value:.4f} on {spec.shape}"
             + (f" (the composed default scored {default.value:.4f})." if default else "."),
             f"# Use it: python -m toolpath.sweep --adopt copies it into conf/model/, then "
             f"dvc exp run -S 'model@models.{spec.model}={spec.tuned_config.stem}'",
             "# `schedule` overrides train.per_shape.<shape> and train.common for this model on every shape."]
    if elsewhere:
        lines.append("# Not representable in a model config, pass as overrides: " + " ".join(elsewhere))
    spec.tuned_config.parent.mkdir(parents=True, exist_ok=True)
    spec.tuned_config.write_text("\n".join(lines) + "\n" + OmegaConf.to_yaml(OmegaConf.create(body)),
                                 encoding="utf-8")
    return spec.tuned_config


def figures(spec: SweepSpec, study: optuna.Study) -> dict[str, str]:
    """Optimisation history and parameter importance (fANOVA, seeded) as PNG; a note where impossible."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from optuna.visualization import matplotlib as plots

    spec.figures.mkdir(parents=True, exist_ok=True)
    written: dict[str, str] = {}
    evaluator = optuna.importance.FanovaImportanceEvaluator(seed=spec.seed)
    makers = {"history": lambda: plots.plot_optimization_history(study, target_name=spec.objective),
              "importance": lambda: plots.plot_param_importances(study, evaluator=evaluator)}
    for name, make in makers.items():
        path = spec.figures / f"sweep_{spec.study}_{name}.png"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            try:
                axes = make()
            except (ValueError, RuntimeError, ZeroDivisionError) as exc:
                written[name] = f"not drawn: {exc}"
                print(f"sweep {spec.study}: {name} figure not drawn ({exc})")
                continue
        axes.figure.savefig(path, dpi=120, bbox_inches="tight", metadata={"Software": None})
        plt.close(axes.figure)
        written[name] = str(path.relative_to(spec.root))
    return written


def finish(spec: SweepSpec, study: optuna.Study, seconds: float | None = None) -> dict[str, Any]:
    """Tag, write the tuned config, the figures and ``reports/sweep/<study>.json``; return that summary."""
    complete = study.get_trials(states=(COMPLETE,))
    if not complete:
        raise RuntimeError(f"study {spec.study}: no trial completed, nothing to report")
    tag_best(spec, study)
    default = default_trial(study)
    best = study.best_trial
    summary = {
        "study": spec.study, "shape": spec.shape, "model": spec.model, "objective": spec.objective,
        "trials": {state.name.lower(): len(study.get_trials(states=(state,)))
                   for state in optuna.trial.TrialState},
        "best": {"number": best.number, "value": best.value, "params": best.params,
                 "val_f1": best.user_attrs.get("val_f1")},
        "default": None if default is None else {"number": default.number, "value": default.value,
                                                 "val_f1": default.user_attrs.get("val_f1")},
        "tuned_config": str(tuned_config(spec, study).relative_to(spec.root)),
        "figures": figures(spec, study),
        "base_overrides": list(spec.base_overrides),
        "seconds_this_run": seconds,
    }
    spec.summary.parent.mkdir(parents=True, exist_ok=True)
    spec.summary.write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    return summary
