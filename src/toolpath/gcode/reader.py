"""Read a G-code program into tool positions: the public entry points.  Run: python -m toolpath.gcode FILE...

The dialect (what is read, what is refused, and every limit) is :mod:`toolpath.gcode.interpreter`'s; a
program read in parts, carrying one interpreter from part to part, is :class:`toolpath.gcode.reading.Reading`.
"""

from __future__ import annotations

from pathlib import Path

from toolpath.gcode.errors import GCodeError
from toolpath.gcode.interpreter import MAX_POINTS, ReaderOptions
from toolpath.gcode.program import MM_PER_INCH, Motion, Program
from toolpath.gcode.reading import Reading
from toolpath.gcode.text import read_bounded

__all__ = ["MAX_POINTS", "MM_PER_INCH", "Motion", "Program", "ReaderOptions", "read_file", "read_text"]


def read_text(text: str, source: str = "<string>", options: ReaderOptions | None = None,
              vectorise: bool = True) -> Program:
    """Interpret G-code text; see the module docstring for the dialect.

    Plain motion lines (:mod:`toolpath.gcode.scanner`) run in vectorised runs, every other line
    through the full interpreter; both give the same numbers, bit for bit (``vectorise=False`` runs
    every line through the interpreter, which the tests compare against).  A program read in parts
    is :class:`toolpath.gcode.reading.Reading`.

    Raises
    ------
    GCodeError
        Naming ``source:line`` for malformed input and unsupported features.
    """
    return Reading(source, options).read(text, vectorise)


def read_file(path: str | Path, options: ReaderOptions | None = None) -> Program:
    """Read a G-code file; bytes that are not UTF-8 are kept (surrogate-escaped), never dropped.

    Raises
    ------
    GCodeError
        For unreadable files (line 0) and for any problem inside them.
    """
    path = Path(path)
    try:
        data = read_bounded(path)
    except OSError as exc:
        raise GCodeError(str(path), 0, f"cannot read file: {exc.strerror or exc}") from None
    return read_text(data.decode("utf-8", errors="surrogateescape"), str(path), options)
