"""Train / validation / test split by program, so neighbouring windows never straddle splits."""

from __future__ import annotations

import numpy as np

SPLIT_NAMES = ("train", "val", "test")


def split_by_program(program_ids: np.ndarray, fractions: tuple[float, float, float],
                     rng: np.random.Generator) -> np.ndarray:
    """Split code (0 train, 1 val, 2 test) for each window, assigned per whole program.

    Programs are shuffled with ``rng`` and dealt out by the cumulative ``fractions`` of the
    program count; each split gets at least one program when there are three or more.
    """
    if not np.isclose(sum(fractions), 1.0):
        raise ValueError(f"split fractions {fractions} do not add up to 1")
    programs = np.unique(program_ids)
    order = rng.permutation(programs)
    n = len(order)
    n_val = max(1, round(fractions[1] * n)) if n >= 3 else 0
    n_test = max(1, round(fractions[2] * n)) if n >= 3 else 0
    code = np.zeros(n, dtype=np.int8)
    code[n - n_test - n_val : n - n_test] = 1
    code[n - n_test :] = 2
    lookup = dict(zip(order.tolist(), code.tolist(), strict=True))
    return np.array([lookup[p] for p in program_ids.tolist()], dtype=np.int8)
