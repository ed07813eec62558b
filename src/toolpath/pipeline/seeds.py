"""Every random draw's seed: the global ``seed`` of the config and stable names (stage, shape ...).

The names are part of the result: renaming one changes its draws, so they stay as they are even where
the stage they name was renamed (the optimize stage still derives its seeds from "optimise")."""

from __future__ import annotations

import zlib

import numpy as np


def seed_for(seed: int, *keys: str) -> int:
    """A 32-bit seed derived from the global ``seed`` and stable names."""
    entropy = [int(seed)] + [zlib.crc32(k.encode()) for k in keys]
    return int(np.random.SeedSequence(entropy).generate_state(1)[0])
