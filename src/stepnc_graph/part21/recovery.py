"""Lenient reading's recovery: where a damaged statement ends (the next instance boundary the
tokenizer finds, never the next line), and how its text is kept -- as an unreadable instance,
a later definition of an ``#id``, or text that names no instance (:class:`UnreadableText`)."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

from stepnc_graph.part21.diagnostics import Diagnostic
from stepnc_graph.part21.model import Instance, UnreadableText
from stepnc_graph.part21.tokens import _Failure

if TYPE_CHECKING:
    from stepnc_graph.part21.reader import Part21Reader

#: inside a string token: a ';' and the start of an instance -- the string may be one whose
#: closing quote is missing (see statement_end)
_CUT = re.compile(r";[ \t\r\n]*#[0-9]+[ \t\r\n]*=")
_ENTITY_NAME = re.compile(r"#[0-9]+[ \t\r\n]*=[ \t\r\n]*([A-Za-z_][A-Za-z0-9_]*)")


def keep_text(r: Part21Reader, start: int, end: int, message: str, section: int) -> None:
    """Lenient: report the text ``start:end`` (up to its last non-blank character) that names
    no instance, and keep it (:class:`UnreadableText`)."""
    end = start + len(r.text[start:end].rstrip())
    line, column = r.position(start)
    r.diagnostics.append(Diagnostic.make("P21-SYNTAX", r.filename, line, column, None,
                                         f"{message}; kept as text"))
    r.unreadable_texts.append(UnreadableText(start, end, line, column, section, message))


def truncate(r: Part21Reader, offset: int, p21_id: int | None) -> None:
    """Lenient: the file ends inside a DATA section (or inside instance ``p21_id``)."""
    r._truncated = True
    inside = f"inside #{p21_id}, which is kept as text; " if p21_id is not None else "inside a DATA section; "
    r._diagnose("P21-TRUNCATED", offset, p21_id,
                f"the file ends {inside}it looks cut short (ENDSEC; and END-ISO-10303-21; are missing); "
                "everything before this point is loaded")


def recover(r: Part21Reader, failure: _Failure, p21_id: int | None, start: int,
            section: int) -> tuple[Instance | None, int]:
    """Report what could not be read and keep its text: as an unreadable instance (when it
    has an ``#id`` not defined before), as a later definition of its ``#id``, or as text
    that names no instance. Returns the instance and the offset where reading goes on."""
    boundary = statement_end(r, start)
    end, resume = boundary if boundary is not None else (len(r.text), len(r.text))
    if boundary is None:  # nothing readable follows: the file stops inside this statement
        truncate(r, start, p21_id)
    if p21_id is None:
        if boundary is None:
            end = start + len(r.text[start:end].rstrip())
            line, column = r.position(start)
            r.unreadable_texts.append(UnreadableText(start, end, line, column, section, failure.message))
        else:
            keep_text(r, start, end, where(r, failure, start), section)
        return None, resume
    r.defined += 1
    if boundary is not None:
        kept = "; kept as text" if p21_id not in r._ids else "; not loaded"
        r._diagnose("P21-SYNTAX", start, p21_id, f"{where(r, failure, start)}{kept}")
    end = start + len(r.text[start:end].rstrip())
    if p21_id in r._ids:
        r.duplicate_texts.append((p21_id, start, end, r.position(start)[0]))
        return None, resume
    r._ids.add(p21_id)
    named = _ENTITY_NAME.match(r.text, start)
    line, column = r.position(start)
    return Instance(p21_id, named.group(1).upper() if named else None, [], line, column, start, end,
                    section=section, unreadable=failure.message), resume


def where(r: Part21Reader, failure: _Failure, start: int) -> str:
    """The failure's message, with its position when that is not the statement's start."""
    if failure.pos == start:
        return failure.message
    line, column = r.position(failure.pos)
    return f"{failure.message} at line {line}, column {column}"


def statement_end(r: Part21Reader, start: int) -> tuple[int, int] | None:
    """(end, resume): where the damaged statement at ``start`` ends and where reading goes
    on; None when the file ends first.

    Tokens are read as the parser reads them, so a ``;`` or ``#12=`` inside a string or
    a comment is no boundary. The statement ends after the first ``;`` outside parentheses
    (or, with its nesting damaged, before the next ``#12=``, ``ENDSEC``, ``DATA;`` or
    ``END-ISO-10303-21`` at any depth). One repair: a string that holds ``;#12=`` and is
    not followed by ``,`` or ``)`` as a parameter must be, is taken to have lost its
    closing quote -- the statement ends at that ``;``, and the next instance starts
    after it, as it does on the next line of a file written one instance a line.
    """
    depth = 0
    pos = start
    cut: int | None = None  # after the ';' in the string just read, if it may be unclosed
    previous = ""
    while True:
        kind, tok, tstart, tend = r._token(pos)
        if cut is not None and tok not in (",", ")"):
            return cut, cut
        cut = None
        if kind == "eof":
            return None
        if kind == "str":
            m = _CUT.search(tok)
            if m is not None:
                cut = tstart + m.start() + 1
        elif tok == "(":
            depth += 1
        elif tok == ")":
            depth = max(depth - 1, 0)
        elif tok == ";" and depth == 0:
            return tend, tend
        elif tstart > start and statement_start(r, kind, tok, tstart, tend, depth, previous):
            return start + len(r.text[start:tstart].rstrip()), tstart
        previous = tok
        pos = tend


def statement_start(r: Part21Reader, kind: str, tok: str, start: int, end: int, depth: int, previous: str) -> bool:
    """Whether the token (``start:end``) starts a statement: an instance ``#12=``, ``ENDSEC``,
    ``END-ISO-10303-21``, ``DATA;``, or ``DATA(`` outside parentheses and not after ``=``
    (where it would be an entity named DATA)."""
    if kind == "ref":
        return r._token(end)[1] == "="
    if kind != "kw":
        return False
    upper = tok.upper()
    if upper == "ENDSEC":
        return True
    if upper == "END":
        return r.text.startswith("END-ISO-10303-21", start)
    if upper == "DATA":
        follows = r._token(end)[1]
        return follows == ";" or (follows == "(" and depth == 0 and previous != "=")
    return False
