"""Summarise G-code files.  Run: python -m toolpath.gcode FILE [FILE ...]

Prints, per file, the point count (rapid / feed), the units the file declared and the bounding box
in mm.  A file that cannot be read prints ``FILE:LINE: message`` on stderr; the exit code is 1 when
any file failed.
"""

from __future__ import annotations

import argparse
import math
import sys

from toolpath.gcode.errors import GCodeError
from toolpath.gcode.reader import Motion, ReaderOptions, read_file


def summarise(path: str, options: ReaderOptions) -> str:
    """One line describing the program at ``path``; raises :class:`GCodeError`."""
    program = read_file(path, options)
    pts, kinds = program.points, program.kinds
    n_rapid = int((kinds == Motion.RAPID).sum())
    if len(pts) == 0:
        return f"{path}: 0 points, units {program.units}, no motion"
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    box = " ".join(f"{a}[{lo[i]:.3f}, {hi[i]:.3f}]" for i, a in enumerate("XYZ"))
    return (f"{path}: {len(pts)} points ({len(pts) - n_rapid} feed, {n_rapid} rapid), "
            f"units {program.units}, bbox mm {box}")


def _positive_mm(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 < value < math.inf:
        raise argparse.ArgumentTypeError(f"{text!r} is not a length > 0 in mm")
    return value


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m toolpath.gcode", description=__doc__.split("\n")[0])
    parser.add_argument("files", nargs="+", help="G-code files (.nc, .ngc, .gcode, .tap ...)")
    parser.add_argument("--chord-tolerance", type=_positive_mm, default=ReaderOptions.chord_tolerance,
                        help="max sagitta (mm) of the chords that replace arcs")
    args = parser.parse_args(argv)
    options = ReaderOptions(chord_tolerance=args.chord_tolerance)
    failed = 0
    for path in args.files:
        try:
            print(summarise(path, options))
        except GCodeError as exc:
            print(exc, file=sys.stderr)
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
