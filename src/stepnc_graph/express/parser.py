"""Parse EXPRESS text into `express-schema` syntax trees, one per SCHEMA.

Adds to the library: nested remarks and odd remark contents (see
:mod:`stepnc_graph.express.comments`), several schemas in one file (the library
parses the first and silently drops the rest), trailing text after the last
``END_SCHEMA`` reported instead of ignored, two grammar fixes (see
:mod:`stepnc_graph.express._patched_parser`), and 1-based positions with the
file name in every error.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import express_schema.lex as lex
import express_schema.parse as ast

from stepnc_graph.express import _patched_parser
from stepnc_graph.express.comments import blank_comments, scan_remarks
from stepnc_graph.express.errors import ExpressSyntaxError


@dataclass(frozen=True)
class ParsedSchema:
    """One SCHEMA block: its syntax tree, the file it came from and its source text.

    ``source`` is the whole original text (remarks included), so later stages
    can quote a declaration's exact source via AST positions.
    """

    tree: ast.Schema
    filename: str
    source: str

    @property
    def name(self) -> str:
        return str(self.tree.identifier).lower()


def _error(text: str, filename: str, line0: int, col0: int, message: str) -> ExpressSyntaxError:
    """Build an error from 0-based line/column as the library reports them."""
    lines = text.splitlines()
    source_line = lines[line0] if 0 <= line0 < len(lines) else ""
    return ExpressSyntaxError(message, filename, line0 + 1, col0 + 1, source_line)


def _position_of_offset(text: str, offset: int) -> tuple[int, int]:
    line0 = text.count("\n", 0, offset)
    col0 = offset - (text.rfind("\n", 0, offset) + 1)
    return line0, col0


def _strip_library_position(message: str) -> str:
    # The library prefixes some messages with its own "at L:C"; we add ours.
    return message.split("\nParsing chain:")[0]


def _split_schemas(tokens: list[lex.Token], text: str, filename: str) -> list[list[lex.Token]]:
    """Cut the token stream into SCHEMA ... END_SCHEMA ; groups."""
    groups: list[list[lex.Token]] = []
    current: list[lex.Token] | None = None
    for tok in tokens:
        if tok.kind is lex.TokenKind.COMMENT:
            continue
        if current is None:
            if tok.kind is not lex.TokenKind.SCHEMA:
                raise _error(text, filename, tok.position.lineno, tok.position.column,
                             f"expected SCHEMA, found {tok.text!r}")
            current = [tok]
            continue
        current.append(tok)
        if tok.kind is lex.TokenKind.SEMI and len(current) >= 2 and current[-2].kind is lex.TokenKind.END_SCHEMA:
            groups.append(current)
            current = None
    if current is not None:
        last = current[-1]
        raise _error(text, filename, last.position.lineno, last.position.column,
                     "unexpected end of input: missing END_SCHEMA;")
    if not groups:
        raise _error(text, filename, 0, 0, "no SCHEMA declaration found")
    return groups


def parse_text(text: str, filename: str = "<string>") -> list[ParsedSchema]:
    """Parse every SCHEMA in ``text``.

    Raises :class:`ExpressSyntaxError` (file, 1-based line and column, the
    source line and a caret) at the first error.
    """
    scan = scan_remarks(text)
    if scan.unterminated is not None:
        line0, col0 = _position_of_offset(text, scan.unterminated)
        raise _error(text, filename, line0, col0, "remark '(*' is never closed")
    clean = blank_comments(text, scan)
    tokens, ok = lex.lex(clean)
    if not ok:
        if tokens:
            end = tokens[-1].start + len(tokens[-1].text)
        else:
            end = 0
        while end < len(clean) and clean[end].isspace():
            end += 1
        line0, col0 = _position_of_offset(clean, end)
        raise _error(text, filename, line0, col0, f"unexpected character {clean[end:end + 1]!r}")
    schemas: list[ParsedSchema] = []
    for group in _split_schemas(list(tokens), text, filename):
        tree, errors = _patched_parser.parse_tokens(group)
        if errors:
            first = errors[0]
            raise _error(text, filename, first.line, first.column, _strip_library_position(first.message))
        assert tree is not None
        schemas.append(ParsedSchema(tree=tree, filename=filename, source=text))
    return schemas


def parse_file(path: str | Path) -> list[ParsedSchema]:
    """Read ``path`` (UTF-8; undecodable bytes replaced) and parse every schema in it."""
    p = Path(path)
    text = p.read_text(encoding="utf-8", errors="replace")
    return parse_text(text, str(p))
