"""Algorithm 1: 50-point windows of cutting motion labelled by LocalCurvature (Table 1)."""

from toolpath.labels.split import Split, split_by_program
from toolpath.labels.windows import (
    CATEGORY_NAMES,
    TABLE1_BOUNDS,
    Windows,
    categorize,
    concat,
    cut_windows,
    feed_runs,
    label_program,
)

__all__ = [
    "CATEGORY_NAMES", "TABLE1_BOUNDS", "Split", "Windows", "categorize", "concat",
    "cut_windows", "feed_runs", "label_program", "split_by_program",
]
