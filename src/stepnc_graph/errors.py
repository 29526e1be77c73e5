"""Errors shared by the project's readers (EXPRESS, Part 21): positioned and JSON-ready."""

from __future__ import annotations

from typing import Any


def render_caret(source_line: str, column: int) -> str:
    """Return the source line and a caret under 1-based ``column``.

    Tabs before the column are kept so the caret lines up in a terminal.
    """
    line = source_line.rstrip("\r\n")
    prefix = "".join(ch if ch == "\t" else " " for ch in line[: max(column - 1, 0)])
    return f"    {line}\n    {prefix}^"


class PositionedSyntaxError(SyntaxError):
    """A `SyntaxError` that knows its file, 1-based line and column, and source line.

    Shared by the EXPRESS and Part 21 readers so that every syntax error of the
    project prints and serialises the same way.
    """

    def __init__(self, message: str, filename: str, line: int, column: int, source_line: str) -> None:
        super().__init__(message, (filename, line, column, source_line))
        self.message = message

    @property
    def line(self) -> int:
        return int(self.lineno or 0)

    @property
    def column(self) -> int:
        return int(self.offset or 0)

    def __str__(self) -> str:
        head = f"{self.filename}:{self.line}:{self.column}: {self.message}"
        if self.text:
            return f"{head}\n{render_caret(self.text, self.column)}"
        return head

    def asdict(self) -> dict[str, Any]:
        """A JSON-ready view of the error."""
        return {
            "type": type(self).__name__,
            "message": self.message,
            "file": self.filename,
            "line": self.line,
            "column": self.column,
            "source_line": (self.text or "").rstrip("\r\n"),
        }
