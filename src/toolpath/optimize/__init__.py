"""Smoothing of rough windows: one problem definition shared by every method, and the smoothers."""

from toolpath.optimize.problem import SmoothingProblem, project_to_tube
from toolpath.optimize.smoothers import bezier_fit, mean_filter

__all__ = ["SmoothingProblem", "bezier_fit", "mean_filter", "project_to_tube"]
