"""The one error type of the G-code package."""

from __future__ import annotations


class GCodeError(ValueError):
    """A G-code problem located at ``source:line``.

    Parameters
    ----------
    source : str
        File name (or ``"<string>"``) the text came from.
    line : int
        1-based line number, 0 when the problem is not tied to one line.
    message : str
        What is wrong, in words a machinist understands.
    """

    def __init__(self, source: str, line: int, message: str) -> None:
        self.source = source
        self.line = line
        self.message = message
        super().__init__(f"{source}:{line}: {message}")

    def __reduce__(self) -> tuple:  # crosses process pools whole (the default would call it with one argument)
        return (GCodeError, (self.source, self.line, self.message))
