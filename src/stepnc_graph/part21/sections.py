"""The sections of a Part 21 file around the instances: HEADER, the edition-3 ANCHOR and
REFERENCE sections, the DATA section openers, the end marker and its SIGNATURE sections. Each
function reads one with the reader's tokens and records it in the reader's ``header``."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any

from stepnc_graph.core.errors import show
from stepnc_graph.part21.parameters import parse_params
from stepnc_graph.part21.recovery import keep_text
from stepnc_graph.part21.tokens import _Failure, _integer
from stepnc_graph.part21.values import Name, Ref

if TYPE_CHECKING:
    from stepnc_graph.part21.reader import Part21Reader

_MAGIC = re.compile(r"(?:[ \t\r\n\f\v]+|/\*.*?\*/)*ISO-10303-21[ \t\r\n]*;", re.S)
_END = re.compile(r"END-ISO-10303-21[ \t\r\n]*;", re.S)
_SIGNATURE = re.compile(r"[ \t\r\n]*(SIGNATURE\b.*?\bENDSEC[ \t\r\n]*;)", re.S)


def read_header(r: Part21Reader) -> int:
    m = _MAGIC.match(r.text)
    if m is None:
        raise r._syntax_error(_Failure("not a Part 21 file: expected 'ISO-10303-21;' at the start",
                                       0, ("ISO-10303-21;",)), None)
    first = len(r.diagnostics)
    try:
        _, _, header_start, _ = r._token(m.end())
        pos = r._expect(m.end(), "HEADER")
        pos = r._expect(pos, ";")
        while True:
            kind, tok, start, end = r._token(pos)
            if kind == "kw" and tok.upper() == "ENDSEC":
                pos = r._expect(end, ";")
                break
            if kind != "kw":
                raise _Failure(f"expected a header entity or ENDSEC, found {show(tok)}", start, ("ENDSEC",))
            params, pos = parse_params(r, end, None)
            pos = r._expect(pos, ";")
            r.header.entities[tok.upper()] = params
    except _Failure as failure:
        raise r._syntax_error(failure, None) from None
    r.header.text = r.text[header_start:pos]
    r.header.repaired = len(r.diagnostics) > first
    for required in ("FILE_DESCRIPTION", "FILE_NAME", "FILE_SCHEMA"):
        if required not in r.header.entities:
            r._diagnose("P21-HEADER", pos, None, f"HEADER has no {required}")
    return pos


def read_reference_sections(r: Part21Reader, pos: int) -> int:
    """The optional edition-3 ANCHOR and REFERENCE sections, in that order."""
    kind, tok, start, end = r._token(pos)
    if kind == "kw" and tok.upper() == "ANCHOR":
        pos = anchor_section(r, r._expect(end, ";"))
        r.header.anchor_text = r.text[start:pos]
        kind, tok, start, end = r._token(pos)
    if kind == "kw" and tok.upper() == "REFERENCE":
        pos = reference_section(r, r._expect(end, ";"))
        r.header.reference_text = r.text[start:pos]
    return pos


def anchor_section(r: Part21Reader, pos: int) -> int:
    """``<name> = item {tags} ;`` entries up to ``ENDSEC;`` (ISO 10303-21:2016, 9)."""
    while True:
        kind, tok, start, end = r._token(pos)
        if kind == "kw" and tok.upper() == "ENDSEC":
            return r._expect(end, ";")
        if kind != "uri":
            raise _Failure(f"expected an anchor name <...> or ENDSEC, found {show(tok)}", start, ("<name>", "ENDSEC"))
        item, pos = anchor_item(r, r._expect(end, "="))
        if isinstance(item, Ref):
            r.header.anchors.append((tok[1:-1], int(item)))
        while True:  # anchor tags: { name : item }
            tkind, ttok, tstart, tend = r._token(pos)
            if ttok != "{":
                break
            nkind, ntok, nstart, nend = r._token(tend)
            if nkind != "kw":
                raise _Failure(f"expected a tag name, found {show(ntok)}", nstart, ("tag name",))
            _, pos = anchor_item(r, r._expect(nend, ":"))
            pos = r._expect(pos, "}")
        pos = r._expect(pos, ";")


def anchor_item(r: Part21Reader, pos: int) -> tuple[Any, int]:
    """One anchor item: a list, an instance or value name, a resource or a simple value."""
    kind, tok, start, end = r._token(pos)
    if tok == "(":
        return parse_params(r, pos, None)
    if kind == "ref":
        return Ref(_integer(tok[1:], start, "an instance name")), end
    if kind in ("name", "uri", "int", "real", "str", "enum", "bin") or tok == "$":
        return Name(tok), end
    raise _Failure(f"expected an anchor item, found {show(tok)}", start, ("#id", "value", "<resource>"))


def reference_section(r: Part21Reader, pos: int) -> int:
    """``#12 = <uri>;`` / ``@12 = <uri>;`` entries up to ``ENDSEC;`` (ISO 10303-21:2016, 10)."""
    while True:
        kind, tok, start, end = r._token(pos)
        if kind == "kw" and tok.upper() == "ENDSEC":
            return r._expect(end, ";")
        if kind not in ("ref", "name") or not tok[1:2].isdigit():  # a constant is not defined here
            raise _Failure(f"expected #id, @id or ENDSEC, found {show(tok)}", start, ("#id", "@id", "ENDSEC"))
        if kind == "ref":
            _integer(tok[1:], start, "an instance name")  # the loader names the instance by it
        ukind, utok, ustart, uend = r._token(r._expect(end, "="))
        if ukind != "uri":
            raise _Failure(f"expected a resource <uri>, found {show(utok)}", ustart, ("<uri>",))
        r.header.references.append((tok, utok[1:-1]))
        pos = r._expect(uend, ";")


def section_start(r: Part21Reader, pos: int) -> int | None:
    """After ``DATA;``/``DATA(...);`` return the offset; at the end of the file return None."""
    kind, tok, start, end = r._token(pos)
    if kind == "kw" and tok.upper() == "DATA":
        params: list[Any] = []
        first = len(r.diagnostics)
        if r._token(end)[1] == "(":
            params, end = parse_params(r, end, None)
        repaired = len(r.diagnostics) > first
        try:
            end = r._expect(end, ";")
            opener = r.text[start:end]
        except _Failure:
            if not (r.lenient and r._statement_follows(end)):
                raise
            r._diagnose("P21-MISSING-SEMICOLON", end, None, "';' missing after DATA; read as present")
            opener = r.text[start:end] + ";"
        r.header.data_sections.append(params)
        r.header.data_section_texts.append(opener)
        r.header.data_section_repaired.append(repaired)
        return end
    m = _END.match(r.text, start)
    if m is not None:
        after = m.end()
        while (sig := _SIGNATURE.match(r.text, after)) is not None:
            r.header.signatures.append(sig.group(1))
            after = sig.end()
        after_end(r, after)
        return None
    if r.lenient and r.text.startswith("END-ISO-10303-21", start):
        r._diagnose("P21-MISSING-SEMICOLON", start, None, "';' missing after END-ISO-10303-21; read as present")
        after_end(r, start + len("END-ISO-10303-21"))
        return None
    if kind == "eof" and r.lenient:
        if not r._truncated:
            r._diagnose("P21-END-MISSING", start, None,
                        "the file ends without 'END-ISO-10303-21;'; everything before it is loaded")
        return None
    raise _Failure(f"expected DATA or END-ISO-10303-21, found {show(tok)}" if tok else
                   "expected DATA or END-ISO-10303-21, found end of file", start,
                   ("DATA", "END-ISO-10303-21;"))


def after_end(r: Part21Reader, pos: int) -> None:
    """Nothing but white space and comments may follow the end marker and its signatures
    (ISO 10303-21:2016, 13): anything else is an error; lenient, kept as text."""
    kind, tok, start, _ = r._token(pos)
    if kind == "eof":
        return
    failure = _Failure(f"text after END-ISO-10303-21;, found {show(tok)}", start, ("end of file",))
    if not r.lenient:
        raise r._syntax_error(failure, None, recoverable=True)
    keep_text(r, start, len(r.text), failure.message, max(len(r.header.data_sections) - 1, 0))
