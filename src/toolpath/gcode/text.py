"""A program's text as lines, the way controllers split it, read within a bound on line length."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from toolpath.gcode.errors import GCodeError

# The longest line read (LinuxCNC's is 256 characters); past it a file is not a program (/dev/zero).
MAX_LINE_LENGTH = 4096
_LINE = re.compile(r"[^\r\n]*(?:\r\n|\r|\n)|[^\r\n]+")


def split_lines(text: str) -> list[str]:
    """Split text into lines that keep their own endings: LF, CRLF or a lone CR (old Mac files, a
    stray CR in a CRLF file), each a line end as controllers read it; nothing else touched."""
    if "\r" not in text:  # the common case, several times faster
        parts = text.split("\n")
        lines = [p + "\n" for p in parts[:-1]]
        if parts[-1]:
            lines.append(parts[-1])
        return lines
    return _LINE.findall(text)


def read_bounded(path: Path, chunk_size: int = 1 << 20) -> bytes:
    """The file's bytes, read in chunks.  A run of bytes without a line end longer than
    :data:`MAX_LINE_LENGTH` allows stops the read with a :class:`GCodeError` naming its line, so an
    endless stream (``/dev/zero``) or a large binary file is refused within a few megabytes.

    Raises
    ------
    OSError
        When the file cannot be opened or read.
    """
    limit = 4 * MAX_LINE_LENGTH  # bytes: UTF-8 takes up to 4 per character
    chunks: list[bytes] = []
    run = 0  # bytes of the unfinished last line so far
    with path.open("rb") as handle:
        while chunk := handle.read(chunk_size):
            codes = np.frombuffer(chunk, np.uint8)
            ends = np.flatnonzero((codes == 10) | (codes == 13))
            if len(ends) == 0:
                longest, run = run + len(chunk), run + len(chunk)
            else:
                longest = max(run + int(ends[0]), int(np.diff(ends).max(initial=1)) - 1)
                run = len(chunk) - 1 - int(ends[-1])
            chunks.append(chunk)
            if max(longest, run) > limit:
                data = b"".join(chunks)
                start = re.search(rb"[^\r\n]{%d}" % (limit + 1), data).start()
                lineno = len(split_lines(data[:start].decode("utf-8", errors="surrogateescape"))) + 1
                raise GCodeError(str(path), lineno, f"the line is longer than {MAX_LINE_LENGTH} characters "
                                                    "(not a G-code program?)")
    return b"".join(chunks)
