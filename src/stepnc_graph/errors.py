"""Errors shared by the project's readers (EXPRESS, Part 21): positioned and JSON-ready.

Source text quoted in a message is user data: a one-line file can be 50 MB and
a damaged one can hold terminal escape sequences. So a quoted line is a window
of :data:`WINDOW` characters each side of the column, with control characters
escaped, and quoted tokens are cut by :func:`show`.
"""

from __future__ import annotations

from typing import Any

#: characters of a source line shown on each side of an error's column
WINDOW = 60
_ELLIPSIS = "..."


class StepncGraphWarning(UserWarning):
    """A warning of stepnc-graph's own (the CLI prints these; other libraries' follow Python's filters)."""


def _escape_char(ch: str) -> str:
    code = ord(ch)
    if ch == "\t" or (0x20 <= code < 0x7F) or code > 0x9F:
        return ch
    return f"\\x{code:02x}"


def excerpt(line: str, column: int) -> tuple[str, int]:
    """A printable window of ``line`` around 1-based ``column`` and the caret's column in it.

    Control characters (C0, DEL, C1: what terminals interpret) become ``\\xNN``;
    a line longer than the window is cut with ``...`` on the cut side(s).
    """
    line = line.rstrip("\r\n")
    index = max(column - 1, 0)
    start = max(index - WINDOW, 0)
    end = min(index + WINDOW, len(line))
    head = _ELLIPSIS if start > 0 else ""
    before = "".join(_escape_char(c) for c in line[start:index])
    after = "".join(_escape_char(c) for c in line[index:end])
    tail = _ELLIPSIS if end < len(line) else ""
    return head + before + after + tail, len(head) + len(before) + 1


def show(token: str, limit: int = 40) -> str:
    """A token quoted for a message: ``repr`` (escapes control characters), cut at ``limit``."""
    if len(token) > limit:
        return repr(token[:limit]) + f"... ({len(token)} characters)"
    return repr(token)


def render_caret(source_line: str, column: int) -> str:
    """Return the (already windowed) source line and a caret under 1-based ``column``.

    Tabs before the column are kept so the caret lines up in a terminal.
    """
    line = source_line.rstrip("\r\n")
    prefix = "".join(ch if ch == "\t" else " " for ch in line[: max(column - 1, 0)])
    return f"    {line}\n    {prefix}^"


class PositionedSyntaxError(SyntaxError):
    """A `SyntaxError` that knows its file, 1-based line and column, and source line.

    Shared by the EXPRESS and Part 21 readers so that every syntax error of the
    project prints and serialises the same way. ``text`` (``source_line`` in
    :meth:`asdict`) is the printable window of the line (see :func:`excerpt`);
    ``excerpt_column`` is where the column falls in it.
    """

    def __init__(self, message: str, filename: str, line: int, column: int, source_line: str) -> None:
        window, self.excerpt_column = excerpt(source_line, column)
        super().__init__(message, (filename, line, column, window))
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
            return f"{head}\n{render_caret(self.text, self.excerpt_column)}"
        return head

    def asdict(self) -> dict[str, Any]:
        """A JSON-ready view of the error."""
        return {
            "type": type(self).__name__,
            "message": self.message,
            "file": self.filename,
            "line": self.line,
            "column": self.column,
            "source_line": self.text or "",
        }
