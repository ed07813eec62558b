"""What every smoothing method returns, so the stage can compare them row by row."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class SmoothingResult:
    """A smoothed window and what it cost.

    ``evaluations`` counts objective evaluations (one candidate window each; an exact gradient counts
    as one evaluation, a central-difference gradient as ``2 x dimension``); ``history`` is the best
    objective after each generation (empty for the one-shot smoothers).
    """

    points: np.ndarray
    objective: float
    evaluations: int
    seconds: float = 0.0
    history: list[float] = field(default_factory=list)
