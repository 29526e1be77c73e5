"""Errors found while resolving schemas into the model."""

from __future__ import annotations

from typing import Any

from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.schema.model import SourcePos


class SchemaError(StepncGraphError):
    """A schema that parses but does not resolve: unknown type, cycle, duplicate name."""

    def __init__(self, message: str, pos: SourcePos | None = None, schema: str | None = None) -> None:
        self.message = message
        self.pos = pos
        self.schema = schema
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.pos}: " if self.pos else ""
        return f"{where}{self.message}"

    def asdict(self) -> dict[str, Any]:
        return {
            "type": type(self).__name__,
            "message": self.message,
            "schema": self.schema,
            "file": self.pos.file if self.pos else None,
            "line": self.pos.line if self.pos else None,
            "column": self.pos.column if self.pos else None,
        }


class SchemaErrors(SchemaError):
    """Several :class:`SchemaError`s found in one build, all reported at once."""

    def __init__(self, errors: list[SchemaError]) -> None:
        self.errors = errors
        first = errors[0]
        super().__init__(first.message, first.pos, first.schema)

    def __str__(self) -> str:
        lines = [f"{len(self.errors)} schema error(s):"]
        lines += [f"  {e}" for e in self.errors]
        return "\n".join(lines)
