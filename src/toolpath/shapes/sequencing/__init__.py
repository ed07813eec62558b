"""Xie & Zhu: S-shaped sequencing by region segmentation of many parts on one sheet, and baselines."""

from toolpath.shapes.sequencing.experiment import METHODS, Outcome, run_sheet, s_shaped
from toolpath.shapes.sequencing.parts import Part
from toolpath.shapes.sequencing.planner import SheetPlan, Visit, part_tree, plan_path
from toolpath.shapes.sequencing.program import sheet_program
from toolpath.shapes.sequencing.regions import Region, s_shaped_regions
from toolpath.shapes.sequencing.score import score
from toolpath.shapes.sequencing.sheets import KINDS, Sheet, make_sheet

__all__ = [
    "KINDS", "METHODS", "Outcome", "Part", "SheetPlan", "Region", "Sheet", "Visit", "make_sheet", "part_tree",
    "plan_path", "run_sheet", "s_shaped", "s_shaped_regions", "score", "sheet_program",
]
