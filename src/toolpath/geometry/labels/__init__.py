"""Algorithm 1: 50-point windows of cutting motion labelled by LocalCurvature (Table 1), and the split
of windows by program.

The names below load on first use (PEP 562), so the split alone (:mod:`toolpath.geometry.labels.split`, which the
windows file's schema uses) does not import the G-code reader.
"""

from importlib import import_module

_HOMES = {"Split": "split", "split_by_program": "split",
          **{name: "categories" for name in ("CATEGORY_NAMES", "TABLE1_BOUNDS", "categorize")},
          **{name: "windows" for name in ("Windows", "concat", "cut_windows", "feed_runs", "label_program")}}

__all__ = sorted(_HOMES)


def __getattr__(name: str):
    if name not in _HOMES:
        raise AttributeError(f"module 'toolpath.geometry.labels' has no attribute {name!r}")
    return getattr(import_module(f"toolpath.geometry.labels.{_HOMES[name]}"), name)
