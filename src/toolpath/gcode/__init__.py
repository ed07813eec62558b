"""RS-274 G-code: read real CAM output into tool positions, write and rewrite G01 programs."""

from toolpath.gcode.errors import GCodeError
from toolpath.gcode.program import LineState, Motion, Program
from toolpath.gcode.reader import ReaderOptions, read_file, read_text
from toolpath.gcode.writer import Pass, ProgramSpec, replace_motion, write_program

__all__ = [
    "GCodeError", "LineState", "Motion", "Pass", "Program", "ProgramSpec", "ReaderOptions",
    "read_file", "read_text", "replace_motion", "write_program",
]
