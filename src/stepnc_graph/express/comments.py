"""Blank out EXPRESS remarks without moving any other character.

Why: the `express-schema` lexer fails on some remark contents (a ``"`` or ``&``
inside a ``--`` tail remark) and does not nest ``(* ... *)`` embedded remarks as
ISO 10303-11 7.1.6.1 requires (real schemas comment out blocks that already
contain remarks). Replacing every remark character except line breaks with a
space keeps each token's line and column exactly where it was, so errors and
AST positions still point into the original file.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RemarkScan:
    """Where the remarks of a text are: ``spans`` of [start, end) offsets.

    ``unterminated`` is the offset of an embedded remark still open at the end
    of the text (an error the caller reports), else ``None``.
    """

    spans: tuple[tuple[int, int], ...]
    unterminated: int | None


def skip_string(text: str, i: int) -> int:
    """Return the index after the string literal that starts at ``i``."""
    quote = text[i]
    j = i + 1
    n = len(text)
    while j < n:
        if text[j] == quote:
            if quote == "'" and j + 1 < n and text[j + 1] == "'":
                j += 2
                continue
            return j + 1
        j += 1
    return n


def _line_end(text: str, i: int) -> int:
    ends = [k for k in (text.find("\n", i), text.find("\r", i)) if k >= 0]
    return min(ends) if ends else len(text)


def scan_remarks(text: str) -> RemarkScan:
    """Find every tail remark (``--``) and nested embedded remark (``(* *)``)."""
    spans: list[tuple[int, int]] = []
    n = len(text)
    i = 0
    while i < n:
        if text.startswith("(*", i):
            start, depth = i, 1
            i += 2
            while i < n and depth:
                if text.startswith("(*", i):
                    depth += 1
                    i += 2
                elif text.startswith("*)", i):
                    depth -= 1
                    i += 2
                else:
                    i += 1
            spans.append((start, i))
            if depth:
                return RemarkScan(tuple(spans), start)
        elif text.startswith("--", i):
            end = _line_end(text, i)
            spans.append((i, end))
            i = end
        elif text[i] in "'\"":
            i = skip_string(text, i)
        else:
            i += 1
    return RemarkScan(tuple(spans), None)


def blank_comments(text: str, scan: RemarkScan | None = None) -> str:
    """Return ``text`` with all remarks replaced by spaces (line breaks kept)."""
    scan = scan or scan_remarks(text)
    out = list(text)
    for start, end in scan.spans:
        for k in range(start, end):
            if out[k] not in "\r\n":
                out[k] = " "
    return "".join(out)
