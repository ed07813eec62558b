"""Smoothing of rough windows: one problem definition shared by every method, and the smoothers."""

from toolpath.smoothing.problem import SmoothingProblem, clip_displacement
from toolpath.smoothing.smoothers import bezier_fit, mean_filter

__all__ = ["SmoothingProblem", "bezier_fit", "clip_displacement", "mean_filter"]
