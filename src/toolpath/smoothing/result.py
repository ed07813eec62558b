"""What every smoothing method returns, so the stage can compare them row by row."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class SmoothingResult:
    """A smoothed window and what it cost.

    ``evaluations`` counts charged objective evaluations (one candidate window each; a gradient, exact or
    by central differences, as the ``2 x dimension`` of Eq. 23); ``history`` is the best objective after
    each generation (empty for the one-shot smoothers).
    """

    points: np.ndarray
    objective: float
    evaluations: int
    seconds: float = 0.0
    history: list[float] = field(default_factory=list)
