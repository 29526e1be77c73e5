"""Errors shared by the project's readers (EXPRESS, Part 21): positioned and JSON-ready.

Source text quoted in a message is user data: a one-line file can be 50 MB and
a damaged one can hold terminal escape sequences. So a quoted line is a window
of :data:`WINDOW` characters each side of the column, with control characters
escaped, and quoted tokens are cut by :func:`show`. Which characters count as
control characters, and how one is written escaped, is defined here once
(:data:`CONTROLS`, :func:`escaped`); the CLI shows every untrusted text with them
(``stepnc_graph.cli.common.terminal_safe``).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Any

#: characters of a source line shown on each side of an error's column
WINDOW = 60
_ELLIPSIS = "..."


#: Who is calling: "api" (Python) or "cli" (the command line sets it for the command it runs).
_SURFACE: ContextVar[str] = ContextVar("stepnc_graph_surface", default="api")


def option(name: str, value: str = "", api: str | None = None) -> str:
    """An option as the caller knows it, for messages: ``--graph IRI`` on the command line,
    ``graph=IRI`` in Python (``api``: the keyword's name where it differs) -- an API error must not
    send a notebook user to a CLI flag."""
    if _SURFACE.get() == "cli":
        return f"--{name.replace('_', '-')}" + (f" {value}" if value else "")
    return f"{api or name.replace('-', '_')}={value or '...'}"


def listed_by() -> str:
    """Where the caller finds the store's programs: the ``info`` command, or ``sg.info(store)``."""
    return "`stepnc-graph info` lists them" if _SURFACE.get() == "cli" else "sg.info(store) lists them"


@contextmanager
def command_line() -> Iterator[None]:
    """Messages raised inside name options as the command line spells them (see :func:`option`)."""
    token = _SURFACE.set("cli")
    try:
        yield
    finally:
        _SURFACE.reset(token)


class StepncGraphError(Exception):
    """The root of every error stepnc-graph reports to a user: bad input or usage (the CLI prints
    it and exits 2). Each subclass keeps the built-in base it had (``ValueError``, ``SyntaxError``,
    ``OSError``), so code that caught those still catches it."""


class StepncGraphWarning(UserWarning):
    """A warning of stepnc-graph's own (the CLI prints these; other libraries' follow Python's filters)."""


#: The characters a terminal acts on instead of showing them, as a regular-expression class body:
#: the C0 controls but tab and line feed (ESC starts every escape sequence; CR returns to the start
#: of the line and so overwrites it), DEL, the C1 controls (U+009B is CSI for a terminal that reads
#: 8-bit controls) and Unicode's bidirectional formatting characters (ALM, LRM, RLM, the embeddings,
#: overrides and isolates), which reorder the text after them: U+202E shows "exe.txt" of "txt.exe".
CONTROLS = "\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u200e\u200f\u202a-\u202e\u2066-\u2069"
_CONTROL = re.compile(f"[{CONTROLS}\n]")


def escaped(character: str, uchar: bool = False) -> str:
    """How a control character is shown: ``\\x1b``, ``\\u202e`` (Python's notation), or ``\\u001b``
    with ``uchar`` (the escape of JSON, Turtle and N-Triples strings, which their readers decode)."""
    code = ord(character)
    return f"\\u{code:04x}" if uchar or code > 0xFF else f"\\x{code:02x}"


def _printable(text: str) -> str:
    return _CONTROL.sub(lambda m: escaped(m.group()), text)


def excerpt(line: str, column: int) -> tuple[str, int]:
    """A printable window of ``line`` around 1-based ``column`` and the caret's column in it.

    Control characters (:data:`CONTROLS`: what terminals interpret) become ``\\xNN`` (``\\uNNNN``);
    a line longer than the window is cut with ``...`` on the cut side(s).
    """
    line = line.rstrip("\r\n")
    index = max(column - 1, 0)
    start = max(index - WINDOW, 0)
    end = min(index + WINDOW, len(line))
    head = _ELLIPSIS if start > 0 else ""
    before = _printable(line[start:index])
    after = _printable(line[index:end])
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


class PositionedSyntaxError(StepncGraphError, SyntaxError):
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
