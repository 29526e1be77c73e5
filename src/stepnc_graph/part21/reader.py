"""Read ISO 10303-21 exchange structures (editions 2 and 3).

Edition 3 (ISO 10303-21:2016) adds, and this reader keeps: an ANCHOR section
(names other files can link to, clause 9), a REFERENCE section (instances and
values defined outside the file, clause 10), several DATA sections with
parameters (clause 11), SIGNATURE sections after the end (clause 13), and the
names ``@12``, ``#CONSTANT``, ``@CONSTANT`` as parameter values (:class:`Name`).

One compiled regular expression tokenizes; a small hand-written parser turns
tokens into :class:`Instance` objects, **one at a time** (``instances()`` is a
generator), so a million-instance file never has its token list or all its
instances in memory -- only its text.

Strict mode raises :class:`Part21SyntaxError` at the first syntax error.
Lenient mode repairs what can be repaired safely (a typographic quote closing
a string, a missing ``;``, an enumeration written without dots, an EXPRESS
remark between instances) with a warning, drops an instance it cannot read with
an error diagnostic naming its ``#id``, and goes on at the next instance.
"""

from __future__ import annotations

import re
from collections.abc import Generator, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stepnc_graph.errors import show
from stepnc_graph.part21.diagnostics import Diagnostic, Part21SyntaxError
from stepnc_graph.part21.source import read_text_source
from stepnc_graph.part21.strings import StringDecodeError, decode
from stepnc_graph.part21.values import DERIVED, UNSET, Binary, Enum, Name, Ref, Typed

TOKEN = re.compile(
    r"""
    (?P<ws>[ \t\r\n\f\v]+|/\*.*?\*/)
  | (?P<ref>\#[0-9]+)
  | (?P<name>[\#@][A-Za-z_][A-Za-z0-9_]*|@[0-9]+)
  | (?P<uri><[^<>\s]*>)
  | (?P<tag>[{}:])
  | (?P<str>'[^']*(?:''[^']*)*')
  | (?P<real>[+-]?[0-9]+\.[0-9]*(?:[Ee][+-]?[0-9]+)?)
  | (?P<int>[+-]?[0-9]+)
  | (?P<enum>\.[A-Za-z_][A-Za-z0-9_]*\.)
  | (?P<kw>!?[A-Za-z_][A-Za-z0-9_]*)
  | (?P<bin>"[0-3][0-9A-Fa-f]*")
  | (?P<p>[=();,$*])
  | (?P<bad>/\*|.)
    """,
    re.X | re.S,
)
_MAGIC = re.compile(r"(?:[ \t\r\n\f\v]+|/\*.*?\*/)*ISO-10303-21[ \t\r\n]*;", re.S)
_END = re.compile(r"END-ISO-10303-21[ \t\r\n]*;", re.S)
_SIGNATURE = re.compile(r"[ \t\r\n]*(SIGNATURE\b.*?\bENDSEC[ \t\r\n]*;)", re.S)
_NEXT_STATEMENT = re.compile(r"(?m)^[ \t]*(?=#[0-9]+[ \t]*=)|\bENDSEC\b")
#: where lenient reading can resume after something that is not a section: an
#: instance, a section keyword or the end marker
_RESUME = re.compile(r"(?m)^[ \t]*(?=#[0-9]+[ \t]*=)|\b(?:DATA|ENDSEC|END-ISO-10303-21)\b")
_DEFINITION = re.compile(r"#([0-9]+)[ \t\r\n]*=")
_COMMENT = re.compile(r"/\*.*?\*/", re.S)
_ENTITY_NAME = re.compile(r"#[0-9]+[ \t\r\n]*=[ \t\r\n]*([A-Za-z_][A-Za-z0-9_]*)")
_INSTANCE_START = re.compile(r"#[0-9]+[ \t\r\n]*=")
_CURLY = "\u2019"
_MAX_DEPTH = 200  # nested lists; deeper input is rejected, not a RecursionError or hang


@dataclass(slots=True)
class Instance:
    """One entity instance: ``#id = NAME(params);`` or a complex ``#id = (A(..) B(..));``.

    ``name`` is upper-case; for complex instances it is None and ``parts``
    holds ``(NAME, params)`` per partial entity, in file order.
    ``start``/``end`` are offsets of the instance's text in the file.
    """

    id: int
    name: str | None
    params: list[Any]
    line: int
    column: int
    start: int
    end: int
    parts: list[tuple[str, list[Any]]] | None = None
    section: int = 0  # which DATA section (0-based) holds the instance
    #: lenient mode: the syntax error of an instance that could not be read.
    #: Such an instance has no parameters; its text (``start:end``) is kept.
    unreadable: str | None = None
    #: lenient mode: the reader repaired the instance's text (a missing ';', a
    #: typographic quote, a bare enumeration), so ``start:end`` is not valid Part 21
    repaired: bool = False

    @property
    def names(self) -> list[str]:
        return [self.name] if self.name is not None else [n for n, _ in self.parts or ()]


@dataclass
class Header:
    """The HEADER section: every entity by upper-case name (FILE_DESCRIPTION, FILE_NAME, ...)."""

    entities: dict[str, list[Any]] = field(default_factory=dict)
    data_sections: list[list[Any]] = field(default_factory=list)
    text: str = ""  # the section verbatim, from HEADER to ENDSEC;
    #: edition 3: the DATA section openers verbatim (``DATA;``, ``DATA('a',('S'));``)
    data_section_texts: list[str] = field(default_factory=list)
    #: edition 3: anchors (name without <>, instance id) that name an instance
    anchors: list[tuple[str, int]] = field(default_factory=list)
    anchor_text: str = ""  # the ANCHOR section verbatim ("" when absent)
    #: edition 3: REFERENCE entries (``#12`` or ``@12``, URI without <>)
    references: list[tuple[str, str]] = field(default_factory=list)
    reference_text: str = ""  # the REFERENCE section verbatim
    signatures: list[str] = field(default_factory=list)  # SIGNATURE sections verbatim
    #: lenient mode repaired the HEADER (a bare enumeration, a typographic quote): ``text``
    #: is not valid Part 21, :func:`stepnc_graph.part21.format.format_header` of it is
    repaired: bool = False

    @property
    def schemas(self) -> list[str]:
        """FILE_SCHEMA's schema names, upper-case."""
        params = self.entities.get("FILE_SCHEMA")
        if not params or not isinstance(params[0], list):
            return []
        return [str(s).upper() for s in params[0] if isinstance(s, str)]


class _Failure(Exception):
    def __init__(self, message: str, pos: int, expected: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.message = message
        self.pos = pos
        self.expected = expected


class Part21Reader:
    """Reader over one file's text. Use :func:`read_text` / :func:`read_file`.

    ``header`` is parsed on construction; ``instances()`` yields the DATA
    instances; ``diagnostics`` collects what lenient mode repaired or dropped
    (strict mode raises instead). ``defined`` counts instance definitions seen.
    """

    def __init__(self, text: str, filename: str = "<string>", lenient: bool = False) -> None:
        self.text = text
        self.filename = filename
        self.lenient = lenient
        self.diagnostics: list[Diagnostic] = []
        self.header = Header()
        self.defined = 0
        self._ids: set[int] = set()
        #: every '/*' from here on has no '*/' after it (checked before matching, so that a
        #: file with many unclosed openers is not rescanned to its end once per opener)
        last_close = text.rfind("*/")
        self._unclosed_from = last_close + 2 if last_close >= 0 else 0
        self._truncated = False  # lenient: the file ended inside a DATA section (reported once)
        #: lenient: later definitions of an #id, not loaded: (#id, start, end, line) of their text
        self.duplicate_texts: list[tuple[int, int, int, int]] = []
        self._line = 1
        self._line_start = 0
        self._cursor = 0  # offset up to which _line/_line_start are exact
        self._pos = self._read_header()
        try:
            self._pos = self._read_reference_sections(self._pos)
        except _Failure as failure:
            raise self._syntax_error(failure, None) from None

    # -- positions ------------------------------------------------------------

    def position(self, offset: int) -> tuple[int, int]:
        """1-based (line, column) of ``offset``; incremental, so cheap when offsets grow."""
        if offset < self._cursor:
            self._line, self._line_start, self._cursor = 1, 0, 0
        text = self.text
        n = text.count("\n", self._cursor, offset)
        if n:
            self._line += n
            self._line_start = text.rfind("\n", self._cursor, offset) + 1
        self._cursor = offset
        return self._line, offset - self._line_start + 1

    def _source_line(self, offset: int) -> str:
        start = self.text.rfind("\n", 0, offset) + 1
        end = self.text.find("\n", offset)
        return self.text[start: end if end >= 0 else len(self.text)]

    def _syntax_error(self, failure: _Failure, p21_id: int | None, recoverable: bool = False) -> Part21SyntaxError:
        """``recoverable``: the error is in the DATA sections, where lenient reading goes on."""
        line, column = self.position(failure.pos)
        return Part21SyntaxError(failure.message, self.filename, line, column, self._source_line(failure.pos),
                                 p21_id, failure.expected, recoverable)

    def _diagnose(self, code: str, offset: int, p21_id: int | None, message: str) -> None:
        line, column = self.position(offset)
        self.diagnostics.append(Diagnostic.make(code, self.filename, line, column, p21_id, message))

    # -- tokens -----------------------------------------------------------------

    def _token(self, pos: int) -> tuple[str, str, int, int]:
        """(kind, text, start, end) of the next token after whitespace and comments."""
        match = TOKEN.match
        text = self.text
        unclosed = self._unclosed_from
        while True:
            if pos >= unclosed and text.startswith("/*", pos):
                return "bad", "/*", pos, pos + 2  # never closed: do not let the regex scan to the end
            m = match(text, pos)
            if m is None:
                return "eof", "", pos, pos
            kind = m.lastgroup or "bad"
            if kind != "ws":
                return kind, m.group(), m.start(), m.end()
            pos = m.end()

    def _expect(self, pos: int, what: str) -> int:
        kind, tok, start, end = self._token(pos)
        if tok.upper() != what:
            found = "end of file" if kind == "eof" else show(tok)
            raise _Failure(f"expected {what!r}, found {found}", start, (what,))
        return end

    # -- values -------------------------------------------------------------------

    def _params(self, pos: int, p21_id: int | None) -> tuple[list[Any], int]:
        """Parse ``( value, ... )`` starting at the ``(`` at or after ``pos``.

        Iterative with an explicit stack (bounded depth), so deep nesting in
        damaged input is an error, never a RecursionError.
        """
        match = TOKEN.match
        text = self.text
        kind, tok, start, pos = self._token(pos)
        if tok != "(":
            raise _Failure(f"expected '(', found {show(tok)}" if tok else "expected '(', found end of file", start, ("(",))
        stack: list[tuple[list[Any], str | None]] = []
        current: list[Any] = []
        typed: str | None = None
        expect_value = True
        unclosed = self._unclosed_from
        while True:
            if pos >= unclosed and text.startswith("/*", pos):
                raise _Failure("comment '/*' is never closed", pos, ("*/",))
            m = match(text, pos)
            if m is None:
                raise _Failure("unexpected end of file inside a parameter list", pos, (")",))
            kind = m.lastgroup or "bad"
            start = pos
            pos = m.end()
            if kind == "ws":
                continue
            tok = m.group()
            if expect_value:
                if kind == "ref":
                    current.append(Ref(tok[1:]))
                elif kind == "real":
                    current.append(float(tok))
                elif kind == "int":
                    current.append(int(tok))
                elif kind == "str":
                    value, pos = self._string(tok, start, pos, p21_id)
                    current.append(value)
                elif kind == "enum":
                    current.append(Enum(tok[1:-1].upper()))
                elif kind == "p":
                    if tok == "$":
                        current.append(UNSET)
                    elif tok == "*":
                        current.append(DERIVED)
                    elif tok == "(":
                        if len(stack) >= _MAX_DEPTH:
                            raise _Failure(f"lists nested deeper than {_MAX_DEPTH}", start)
                        stack.append((current, typed))
                        current, typed = [], None
                        continue
                    elif tok == ")" and not current and typed is None:
                        expect_value = False  # empty list
                        pos = start
                        continue
                    else:
                        raise _Failure(f"expected a parameter value, found {show(tok)}", start,
                                       ("value", "$", "*", "("))
                elif kind == "kw":
                    nkind, ntok, nstart, nend = self._token(pos)
                    if ntok == "(":
                        if len(stack) >= _MAX_DEPTH:
                            raise _Failure(f"lists nested deeper than {_MAX_DEPTH}", start)
                        stack.append((current, typed))
                        current, typed, pos = [], tok.upper(), nend
                        continue
                    if not self.lenient:
                        raise _Failure(f"expected a parameter value, found {show(tok)} (enumeration values are "
                                       f"written .{tok.upper()}.)", start, ("value",))
                    self._diagnose("P21-BARE-ENUM", start, p21_id, f"{show(tok)} read as .{tok.upper()[:40]}.")
                    current.append(Enum(tok.upper()))
                elif kind == "bin":
                    current.append(Binary(tok[1:-1]))
                elif kind == "name":
                    current.append(Name(tok))
                else:
                    raise self._bad_token(kind, tok, start, ("value",))
                expect_value = False
            else:
                if tok == ",":
                    expect_value = True
                elif tok == ")":
                    finished, finished_typed = current, typed
                    if not stack:
                        return finished, pos
                    current, typed = stack.pop()
                    if finished_typed is not None:
                        if len(finished) != 1:
                            raise _Failure(f"typed parameter {finished_typed} needs exactly one value", start)
                        current.append(Typed(finished_typed, finished[0]))
                    else:
                        current.append(finished)
                else:
                    raise self._bad_token(kind or "bad", tok, start, (",", ")"))

    def _bad_token(self, kind: str, tok: str, start: int, expected: tuple[str, ...]) -> _Failure:
        if kind == "bad" and tok == "'":
            return _Failure("string is never closed", start, ("'",))
        if kind == "bad" and tok == "/*":
            return _Failure("comment '/*' is never closed", start, ("*/",))
        return _Failure(f"expected {' or '.join(repr(e) for e in expected)}, found {show(tok)}", start, expected)

    def _string(self, tok: str, start: int, end: int, p21_id: int | None) -> tuple[str, int]:
        """Decode a string token; in lenient mode repair a typographic closing quote."""
        if self.lenient and "\n" in tok:
            first_break = tok.index("\n")
            k = tok.find(_CURLY, 0, first_break)
            if k > 0 and _INSTANCE_START.search(tok, first_break):
                self._diagnose("P21-CURLY-QUOTE", start + k, p21_id,
                               "string closed by a typographic quote (U+2019); read as closed there")
                tok, end = tok[:k] + "'", start + k + 1
        try:
            return decode(tok[1:-1]), end
        except StringDecodeError as e:
            raise _Failure(str(e), start + 1 + e.offset) from None

    # -- sections -------------------------------------------------------------------

    def _read_header(self) -> int:
        m = _MAGIC.match(self.text)
        if m is None:
            raise self._syntax_error(_Failure("not a Part 21 file: expected 'ISO-10303-21;' at the start",
                                              0, ("ISO-10303-21;",)), None)
        first = len(self.diagnostics)
        try:
            _, _, header_start, _ = self._token(m.end())
            pos = self._expect(m.end(), "HEADER")
            pos = self._expect(pos, ";")
            while True:
                kind, tok, start, end = self._token(pos)
                if kind == "kw" and tok.upper() == "ENDSEC":
                    pos = self._expect(end, ";")
                    break
                if kind != "kw":
                    raise _Failure(f"expected a header entity or ENDSEC, found {show(tok)}", start, ("ENDSEC",))
                params, pos = self._params(end, None)
                pos = self._expect(pos, ";")
                self.header.entities[tok.upper()] = params
        except _Failure as failure:
            raise self._syntax_error(failure, None) from None
        self.header.text = self.text[header_start:pos]
        self.header.repaired = len(self.diagnostics) > first
        for required in ("FILE_DESCRIPTION", "FILE_NAME", "FILE_SCHEMA"):
            if required not in self.header.entities:
                self._diagnose("P21-HEADER", pos, None, f"HEADER has no {required}")
        return pos

    def _read_reference_sections(self, pos: int) -> int:
        """The optional edition-3 ANCHOR and REFERENCE sections, in that order."""
        kind, tok, start, end = self._token(pos)
        if kind == "kw" and tok.upper() == "ANCHOR":
            pos = self._anchor_section(self._expect(end, ";"))
            self.header.anchor_text = self.text[start:pos]
            kind, tok, start, end = self._token(pos)
        if kind == "kw" and tok.upper() == "REFERENCE":
            pos = self._reference_section(self._expect(end, ";"))
            self.header.reference_text = self.text[start:pos]
        return pos

    def _anchor_section(self, pos: int) -> int:
        """``<name> = item {tags} ;`` entries up to ``ENDSEC;`` (ISO 10303-21:2016, 9)."""
        while True:
            kind, tok, start, end = self._token(pos)
            if kind == "kw" and tok.upper() == "ENDSEC":
                return self._expect(end, ";")
            if kind != "uri":
                raise _Failure(f"expected an anchor name <...> or ENDSEC, found {show(tok)}", start, ("<name>", "ENDSEC"))
            item, pos = self._anchor_item(self._expect(end, "="))
            if isinstance(item, Ref):
                self.header.anchors.append((tok[1:-1], int(item)))
            while True:  # anchor tags: { name : item }
                tkind, ttok, tstart, tend = self._token(pos)
                if ttok != "{":
                    break
                nkind, ntok, nstart, nend = self._token(tend)
                if nkind != "kw":
                    raise _Failure(f"expected a tag name, found {show(ntok)}", nstart, ("tag name",))
                _, pos = self._anchor_item(self._expect(nend, ":"))
                pos = self._expect(pos, "}")
            pos = self._expect(pos, ";")

    def _anchor_item(self, pos: int) -> tuple[Any, int]:
        """One anchor item: a list, an instance or value name, a resource or a simple value."""
        kind, tok, start, end = self._token(pos)
        if tok == "(":
            return self._params(pos, None)
        if kind == "ref":
            return Ref(tok[1:]), end
        if kind in ("name", "uri", "int", "real", "str", "enum", "bin") or tok == "$":
            return Name(tok), end
        raise _Failure(f"expected an anchor item, found {show(tok)}", start, ("#id", "value", "<resource>"))

    def _reference_section(self, pos: int) -> int:
        """``#12 = <uri>;`` / ``@12 = <uri>;`` entries up to ``ENDSEC;`` (ISO 10303-21:2016, 10)."""
        while True:
            kind, tok, start, end = self._token(pos)
            if kind == "kw" and tok.upper() == "ENDSEC":
                return self._expect(end, ";")
            if kind not in ("ref", "name") or not tok[1:2].isdigit():  # a constant is not defined here
                raise _Failure(f"expected #id, @id or ENDSEC, found {show(tok)}", start, ("#id", "@id", "ENDSEC"))
            ukind, utok, ustart, uend = self._token(self._expect(end, "="))
            if ukind != "uri":
                raise _Failure(f"expected a resource <uri>, found {show(utok)}", ustart, ("<uri>",))
            self.header.references.append((tok, utok[1:-1]))
            pos = self._expect(uend, ";")

    def _section_start(self, pos: int) -> int | None:
        """After ``DATA;``/``DATA(...);`` return the offset; at the end of the file return None."""
        kind, tok, start, end = self._token(pos)
        if kind == "kw" and tok.upper() == "DATA":
            nkind, ntok, _, nend = self._token(end)
            if ntok == "(":
                params, end = self._params(end, None)
                self.header.data_sections.append(params)
            else:
                self.header.data_sections.append([])
            end = self._expect(end, ";")
            self.header.data_section_texts.append(self.text[start:end])
            return end
        m = _END.match(self.text, start)
        if m is not None:
            after = m.end()
            while (sig := _SIGNATURE.match(self.text, after)) is not None:
                self.header.signatures.append(sig.group(1))
                after = sig.end()
            return None
        if self.lenient and self.text.startswith("END-ISO-10303-21", start):
            self._diagnose("P21-MISSING-SEMICOLON", start, None, "';' missing after END-ISO-10303-21; read as present")
            return None
        if kind == "eof" and self.lenient:
            if not self._truncated:
                self._diagnose("P21-END-MISSING", start, None,
                               "the file ends without 'END-ISO-10303-21;'; everything before it is loaded")
            return None
        raise _Failure(f"expected DATA or END-ISO-10303-21, found {show(tok)}" if tok else
                       "expected DATA or END-ISO-10303-21, found end of file", start,
                       ("DATA", "END-ISO-10303-21;"))

    def instances(self) -> Iterator[Instance]:
        """Yield every instance of every DATA section, in file order."""
        pos = self._pos
        while True:
            section = self._next_section(pos)
            if section is None:
                return
            pos = yield from self._data_section(section, len(self.header.data_sections) - 1)

    def _next_section(self, pos: int) -> int | None:
        """The offset after the next section opener; None at the end of the file.

        Lenient: text where a section should start is skipped (and reported) up to
        the next instance or section keyword; an instance found there is read into
        the preceding DATA section.
        """
        while True:
            try:
                return self._section_start(pos)
            except _Failure as failure:
                if not self.lenient:
                    raise self._syntax_error(failure, None, recoverable=True) from None
                stop, message = failure.pos, failure.message
            kind, tok, start, _ = self._token(stop)
            if kind == "ref" and _INSTANCE_START.match(self.text, start):
                self._diagnose("P21-OUTSIDE-SECTION", start, int(tok[1:]),
                               "instance outside a DATA section; read into the preceding one")
                if not self.header.data_sections:
                    self.header.data_sections.append([])
                    self.header.data_section_texts.append("DATA;")
                return start
            m = _RESUME.search(self.text, stop + 1)
            skipped = self.text[stop: m.start() if m else len(self.text)].strip()
            if skipped:
                self._diagnose("P21-SYNTAX", stop, None, f"{message}; {len(skipped)} characters skipped")
            if m is None:
                self._truncated = True  # reported: no end-marker warning on top
                return None
            pos = m.start()

    def _data_section(self, pos: int, index: int) -> Generator[Instance, None, int]:
        while True:
            kind, tok, start, end = self._token(pos)
            if kind == "kw" and tok.upper() == "ENDSEC":
                return self._end_of_section(end)
            if kind == "p" and tok == "(" and self.lenient and self.text.startswith("(*", start):
                close = self.text.find("*)", start + 2)
                if close >= 0:
                    self._diagnose("P21-EXPRESS-REMARK", start, None, "EXPRESS remark between instances skipped")
                    pos = close + 2
                    continue
            if kind == "eof":
                if not self.lenient:
                    raise self._syntax_error(_Failure("unexpected end of file in DATA section", start, ("ENDSEC",)),
                                             None, recoverable=True)
                if not self._truncated:
                    self._truncate(start, None)
                return start
            p21_id = int(tok[1:]) if kind == "ref" else None
            first = len(self.diagnostics)
            try:
                if p21_id is None:
                    raise self._bad_token(kind, tok, start, ("#id", "ENDSEC"))
                instance, pos = self._instance(p21_id, start, end)
            except _Failure as failure:
                if not self.lenient:
                    raise self._syntax_error(failure, p21_id, recoverable=True) from None
                broken, pos = self._recover(failure, p21_id, start)
                if broken is not None:
                    broken.section = index
                    yield broken
                continue
            instance.repaired = len(self.diagnostics) > first
            self.defined += 1
            if instance.id in self._ids:
                message = f"#{instance.id} is defined again; this later definition is not loaded"
                if not self.lenient:
                    raise self._syntax_error(_Failure(message, start, ()), instance.id, recoverable=True)
                self._diagnose("P21-DUPLICATE-ID", start, instance.id, message)
                self.duplicate_texts.append((instance.id, start, instance.end, instance.line))
                continue
            self._ids.add(instance.id)
            instance.section = index
            yield instance

    def _end_of_section(self, end: int) -> int:
        """After ``ENDSEC``: its ``;`` (lenient: a missing one is reported and assumed)."""
        try:
            return self._expect(end, ";")
        except _Failure as failure:
            if not self.lenient:
                raise self._syntax_error(failure, None, recoverable=True) from None
            self._diagnose("P21-MISSING-SEMICOLON", end, None, "';' missing after ENDSEC; read as present")
            return end

    def _truncate(self, offset: int, p21_id: int | None) -> None:
        """Lenient: the file ends inside a DATA section (or inside instance ``p21_id``)."""
        self._truncated = True
        inside = f"inside #{p21_id}, which is kept as text; " if p21_id is not None else "inside a DATA section; "
        self._diagnose("P21-TRUNCATED", offset, p21_id,
                       f"the file ends {inside}it looks cut short (ENDSEC; and END-ISO-10303-21; are missing); "
                       "everything before this point is loaded")

    def _instance(self, p21_id: int, start: int, pos: int) -> tuple[Instance, int]:
        pos = self._expect(pos, "=")
        kind, tok, tstart, tend = self._token(pos)
        if kind == "kw":
            params, pos = self._params(tend, p21_id)
            name: str | None = tok.upper()
            parts = None
        elif tok == "(":
            name, params, parts = None, [], []
            pos = tend
            while True:
                kind, tok, tstart, tend = self._token(pos)
                if tok == ")":
                    pos = tend
                    break
                if kind != "kw":
                    raise _Failure(f"expected an entity name or ')' in a complex instance, found {show(tok)}", tstart,
                                   ("entity name", ")"))
                part_params, pos = self._params(tend, p21_id)
                parts.append((tok.upper(), part_params))
            if not parts:
                raise _Failure("empty complex instance", tstart, ("entity name",))
        else:
            raise _Failure(f"expected an entity name or '(', found {show(tok)}", tstart, ("entity name", "("))
        kind, tok, tstart, tend = self._token(pos)
        if tok == ";":
            end = tend
        elif self.lenient and (kind == "eof" or (kind == "ref" and _INSTANCE_START.match(self.text, tstart))
                               or (kind == "kw" and tok.upper() == "ENDSEC")):
            self._diagnose("P21-MISSING-SEMICOLON", pos, p21_id, "';' missing after the instance; read as present")
            end = pos
        else:
            raise _Failure(f"expected ';', found {show(tok)}" if tok else "expected ';', found end of file", tstart,
                           (";",))
        line, column = self.position(start)
        return Instance(p21_id, name, params, line, column, start, end, parts), end

    def _recover(self, failure: _Failure, p21_id: int | None, start: int) -> tuple[Instance | None, int]:
        """Report what could not be read; return it as an unreadable instance (when it has
        an ``#id`` not defined before) and the offset of the next statement."""
        m = _NEXT_STATEMENT.search(self.text, max(failure.pos, start + 1))
        resume = m.start() if m else len(self.text)
        at_end = m is None  # nothing readable follows: the file stops inside this statement
        if p21_id is not None:
            self.defined += 1
        if at_end:  # the file stops inside this statement
            self._truncate(start, p21_id)
        else:
            line, column = self.position(failure.pos)
            where = f" at line {line}, column {column}" if failure.pos != start else ""
            kept = "; kept as text" if p21_id is not None and p21_id not in self._ids else "; not loaded"
            self._diagnose("P21-SYNTAX", start, p21_id, f"{failure.message}{where}{kept}")
        if p21_id is None:
            return None, resume
        end = start + len(self.text[start:resume].rstrip())
        if p21_id in self._ids:
            self.duplicate_texts.append((p21_id, start, end, self.position(start)[0]))
            return None, resume
        self._ids.add(p21_id)
        named = _ENTITY_NAME.match(self.text, start)
        line, column = self.position(start)
        return Instance(p21_id, named.group(1).upper() if named else None, [], line, column, start, end,
                        unreadable=failure.message), resume


def defined_ids(text: str) -> set[int]:
    """The ``#id``s a file's text defines (``#12=``), not counting text in comments.

    The loader needs the set before reading (references point forward as well
    as back) to tell an unresolved reference. Comments are left out because
    the writer keeps unreadable instances in comments; strings are not, since a
    damaged string (a typographic closing quote) would hide every definition up
    to the next quote. Linear: only openers before the last ``*/`` are matched
    as comments, so an unclosed ``/*`` never makes the regex rescan the tail.
    """
    if "/*" in text:
        closed = text.rfind("*/") + 2
        text = _COMMENT.sub(" ", text[:closed]) + text[closed:] if closed > 1 else text
    return {int(x) for x in _DEFINITION.findall(text)}


def read_text(text: str, filename: str = "<string>", lenient: bool = False) -> Part21Reader:
    """A reader over ``text`` (header already parsed; iterate ``instances()``)."""
    return Part21Reader(text, filename, lenient)


def read_file(path: str | Path, lenient: bool = False) -> Part21Reader:
    """Read ``path``: UTF-8 where it is UTF-8, other bytes as ISO 8859-1, each reported
    (see :mod:`stepnc_graph.part21.source`)."""
    text, _, encoding = read_text_source(path)
    reader = Part21Reader(text, str(path), lenient)
    reader.diagnostics[:0] = encoding
    return reader
