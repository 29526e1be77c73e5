"""Diagnostics and the syntax error of the Part 21 reader and loader.

Every problem found in a Part 21 file is a :class:`Diagnostic` with a stable
code (listed in ``CODES``), a severity, and where it is: file, line, column and
the ``#id`` of the instance. Fatal syntax errors in strict mode are raised as
:class:`Part21SyntaxError`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

from stepnc_graph.core.errors import PositionedSyntaxError

Severity = Literal["error", "warning", "info"]

CODES: dict[str, tuple[Severity, str]] = {
    # syntax (reader)
    "P21-SYNTAX": ("error", "the instance does not parse; its text is kept (p21:UnreadableInstance, or "
                            "p21:unreadableText when no #id names it)"),
    "P21-DUPLICATE-ID": ("error", "an instance name is defined twice; the later definition's text is kept, "
                                  "not loaded"),
    "P21-TRUNCATED": ("error", "the file ends inside a DATA section: it looks cut short"),
    "P21-END-MISSING": ("warning", "END-ISO-10303-21; is missing at the end of the file"),
    "P21-ENDSEC-MISSING": ("warning", "ENDSEC; is missing before the next DATA section or END-ISO-10303-21;"),
    "P21-OUTSIDE-SECTION": ("warning", "an instance outside a DATA section; read into the preceding one"),
    "P21-ENCODING": ("warning", "a byte that is not UTF-8; read as ISO 8859-1"),
    "P21-CURLY-QUOTE": ("warning", "a string was closed by a typographic quote; read as closed there"),
    "P21-MISSING-SEMICOLON": ("warning", "';' missing after an instance; read as if present"),
    "P21-BARE-ENUM": ("warning", "an enumeration value written without dots; read as .VALUE."),
    "P21-EXPRESS-REMARK": ("warning", "an EXPRESS remark (* ... *) between instances; skipped"),
    "P21-HEADER": ("warning", "a HEADER entity is missing or malformed"),
    # schema level (loader)
    "P21-UNKNOWN-ENTITY": ("error", "the entity name is not in the schema; instance kept raw"),
    "P21-ARGUMENT-COUNT": ("error", "wrong number of parameters; instance kept raw"),
    "P21-VALUE-TYPE": ("error", "a parameter value does not fit the attribute's type; instance kept raw"),
    "P21-ABSTRACT": ("warning", "an instance of an ABSTRACT entity"),
    "P21-UNRESOLVED-REF": ("error", "a reference to an instance the file does not define"),
    "P21-UNKNOWN-SCHEMA": ("warning", "FILE_SCHEMA names a schema stepnc-graph does not know"),
}


@dataclass(frozen=True)
class Diagnostic:
    code: str
    severity: Severity
    file: str
    line: int
    column: int
    p21_id: int | None
    message: str

    @classmethod
    def make(cls, code: str, file: str, line: int, column: int, p21_id: int | None, message: str) -> "Diagnostic":
        return cls(code, CODES[code][0], file, line, column, p21_id, message)

    def asdict(self) -> dict[str, Any]:
        return asdict(self)

    def __str__(self) -> str:
        ident = f" #{self.p21_id}" if self.p21_id is not None else ""
        return f"{self.file}:{self.line}:{self.column}:{ident} {self.severity} {self.code}: {self.message}"


class Part21SyntaxError(PositionedSyntaxError):
    """A Part 21 file that does not parse, with the ``#id`` and what was expected.

    ``recoverable`` is true for an error in the DATA sections: lenient reading
    would report it and go on (the CLI suggests ``--lenient`` only then).
    """

    def __init__(self, message: str, filename: str, line: int, column: int, source_line: str,
                 p21_id: int | None = None, expected: tuple[str, ...] = (), recoverable: bool = False) -> None:
        super().__init__(message, filename, line, column, source_line)
        self.p21_id = p21_id
        self.expected = expected
        self.recoverable = recoverable

    def asdict(self) -> dict[str, Any]:
        return {**super().asdict(), "p21_id": self.p21_id, "expected": list(self.expected)}

    def __str__(self) -> str:
        text = super().__str__()
        if self.p21_id is not None:
            head, _, rest = text.partition("\n")
            text = head.replace(": ", f": #{self.p21_id}: ", 1) + ("\n" + rest if rest else "")
        return text
