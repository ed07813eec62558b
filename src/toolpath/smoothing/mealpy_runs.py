"""Metaheuristic baselines from mealpy on the same problem, budget, start and seed as NACOA.

mealpy 3.0.3 is installed by the Makefile with ``--no-deps`` (its numpy pin would downgrade numpy; see
``../shared/platform-notes.md``).  Notes the report repeats:

* ``mealpy.COA`` is the *Coyote* algorithm; the Coati algorithm is ``swarm_based.CoatiOA.OriginalCoatiOA``;
* ``HBA.OriginalHBA`` has a known bug (mealpy issue 279): its density factor stays near 0.736 instead
  of decaying, so it explores less late in the run than the HBA paper intends;
* CoatiOA and ESOA are drawn towards the origin of the search space.  Our origin (zero displacement)
  is the original window, a good point, which would flatter them; every algorithm therefore also
  runs on a *shifted* encoding, ``y = x + shift`` with a fixed random ``shift`` inside the box, so the
  origin of ``y`` lies elsewhere and a ranking that depends on the bias shows up as a difference.

mealpy checks its budget after each generation, so a run may use up to one population more than
``budget`` evaluations; the count mealpy reports is the one recorded.
"""

from __future__ import annotations

import importlib
import time

import numpy as np

from toolpath.smoothing.problem import SmoothingProblem
from toolpath.smoothing.result import SmoothingResult

MEALPY_CLASSES = {
    "coa": "mealpy.swarm_based.CoatiOA.OriginalCoatiOA",
    "hba": "mealpy.swarm_based.HBA.OriginalHBA",
    "avoa": "mealpy.swarm_based.AVOA.OriginalAVOA",
    "scso": "toolpath.smoothing.scso.VectorisedSCSO",  # mealpy's OriginalSCSO, one generation per array op
    "esoa": "mealpy.swarm_based.ESOA.OriginalESOA",
    "pso": "mealpy.swarm_based.PSO.OriginalPSO",
}


class MealpyMissing(RuntimeError):
    """mealpy is not installed (it is installed by ``make install`` with ``--no-deps``)."""


def _optimizer_class(name: str):
    if name not in MEALPY_CLASSES:
        raise ValueError(f"unknown mealpy baseline {name!r}; known: {', '.join(MEALPY_CLASSES)}")
    module, _, cls = MEALPY_CLASSES[name].rpartition(".")
    try:
        return getattr(importlib.import_module(module), cls)
    except ImportError as exc:
        raise MealpyMissing("mealpy is not installed: run `make install` "
                            "(pip install --no-deps mealpy==3.0.3)") from exc


def encoding_shift(problem: SmoothingProblem, box: float, seed: int) -> np.ndarray:
    """The fixed offset of the shifted encoding: uniform in ``[-box, box]`` per coordinate."""
    return np.random.default_rng(seed).uniform(-box, box, problem.dimension)


def run_mealpy(name: str, problem: SmoothingProblem, *, population: int, budget: int, box: float, seed: int,
               start: np.ndarray | None = None, shift: np.ndarray | None = None) -> SmoothingResult:
    """Minimise ``problem`` with mealpy's ``name`` inside ``[-box, box]`` per displacement coordinate.

    ``start`` (population, dimension) are the starting decision vectors (NACOA's first population, so
    every method starts from the same candidates); ``shift`` turns on the shifted encoding.
    """
    from mealpy import FloatVar

    cls = _optimizer_class(name)
    offset = np.zeros(problem.dimension) if shift is None else np.asarray(shift, dtype=np.float64)
    bounds = FloatVar(lb=(-box + offset).tolist(), ub=(box + offset).tolist())
    spec = {"bounds": bounds, "minmax": "min", "log_to": None,
            "obj_func": lambda y: float(problem.objective(np.asarray(y) - offset))}
    model = cls(epoch=budget // population + 1, pop_size=population)
    starting = None if start is None else np.clip(start + offset, -box + offset, box + offset)
    began = time.perf_counter()
    best = model.solve(spec, termination={"max_fe": budget}, starting_solutions=starting, seed=seed)
    seconds = time.perf_counter() - began
    x = np.asarray(best.solution) - offset
    return SmoothingResult(points=problem.points(x), objective=float(best.target.fitness),
                           evaluations=int(model.nfe_counter), seconds=seconds,
                           history=[float(v) for v in model.history.list_global_best_fit])
