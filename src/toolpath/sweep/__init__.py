"""Hyperparameter sweeps outside the DVC stages: Optuna (TPE, seeded) over ``conf/sweep/<name>.yaml``,
each trial's config composed by Hydra from ``conf/``, every trial a nested MLflow run.

Run: ``python -m toolpath.sweep [--config mcrl] [--trials K] [OVERRIDE ...]``.  Grid sweeps of the
pipeline itself go through DVC's experiment queue instead (see the README).
"""

from toolpath.sweep.space import Param, overrides, parse_space, suggest

__all__ = ["Param", "overrides", "parse_space", "suggest"]
