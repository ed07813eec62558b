"""Train / validation / test split by program, so neighbouring windows never straddle splits."""

from __future__ import annotations

import warnings

import numpy as np

from toolpath.pipeline.artifacts import Split  # the windows file's split codes


def split_by_program(program_ids: np.ndarray, labels: np.ndarray, fractions: tuple[float, float, float],
                     seed: int) -> np.ndarray:
    """:class:`Split` code for each window, assigned per whole program.

    scikit-learn's ``StratifiedGroupKFold`` deals whole programs (groups) into ``k`` folds whose
    class mixes are as close as the programs allow, where ``k = round(1 / min(val, test))``; the
    first ``round(test * k)`` folds are the test split, the next ``round(val * k)`` the validation
    split.  Roughness varies from program to program, so a plain random deal of a few dozen
    programs can leave a split without rough windows; stratifying keeps every split representative.
    The realised fractions are multiples of ``1 / k`` (0.15 gives k = 7: 1/7 each).
    """
    if not np.isclose(sum(fractions), 1.0):
        raise ValueError(f"split fractions {fractions} do not add up to 1")
    _, val, test = fractions
    k = max(3, round(1.0 / min(val, test)))
    n_test, n_val = max(1, round(test * k)), max(1, round(val * k))
    n_programs = len(np.unique(program_ids))
    if n_programs < k:
        raise ValueError(f"{n_programs} programs cannot fill {k} folds; generate more programs")
    from sklearn.model_selection import StratifiedGroupKFold  # here: 3 s of imports every stage would pay

    folds = StratifiedGroupKFold(n_splits=k, shuffle=True, random_state=seed)
    code = np.zeros(len(program_ids), dtype=np.int8)
    with warnings.catch_warnings():
        # a class rarer than k windows cannot reach every fold; the deal is still by program
        warnings.filterwarnings("ignore", message="The least populated class in y", category=UserWarning)
        held_out = [held for _, held in folds.split(np.zeros(len(labels)), labels, program_ids)]
    for f, held in enumerate(held_out):
        if f < n_test:
            code[held] = Split.TEST
        elif f < n_test + n_val:
            code[held] = Split.VAL
    return code
