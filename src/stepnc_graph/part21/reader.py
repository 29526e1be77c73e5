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
remark between instances) with a warning, keeps an instance it cannot read as
its text with an error diagnostic naming its ``#id``, and goes on at the next
instance boundary -- the end of the statement, found by the tokenizer (so a
``;`` inside a string is none), or the next ``#12=`` -- never at the next line:
files written on one line exist. Text that names no instance (``#=A(1);``,
junk between sections, text after the end marker) is kept as well
(:class:`UnreadableText`): every byte of the file is data, structure, a comment
or reported text.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Generator, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stepnc_graph.core.errors import show
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
#: inside a string token: a ';' and the start of an instance -- the string may be one whose
#: closing quote is missing (see Part21Reader._boundary)
_CUT = re.compile(r";[ \t\r\n]*#[0-9]+[ \t\r\n]*=")
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


@dataclass(frozen=True, slots=True)
class UnreadableText:
    """Lenient mode: text that is no instance the reader could name -- an instance whose
    ``#id`` is damaged (``#=A(1);``), junk between instances or sections, text after
    ``END-ISO-10303-21;`` -- kept (``start:end`` of the file) so that nothing is lost."""

    start: int
    end: int
    line: int
    column: int
    section: int  # the DATA section (0-based) it is in or follows
    reason: str  # the syntax error, as reported


def _integer(digits: str, pos: int, what: str) -> int:
    """``int(digits)``, or the syntax error for an integer longer than the interpreter reads
    (``sys.get_int_max_str_digits()``, 4,300 by default: ``int()`` refuses more)."""
    try:
        return int(digits)
    except ValueError:
        raise _too_long(digits, pos, what) from None


def _too_long(digits: str, pos: int, what: str) -> "_Failure":
    n = len(digits.lstrip("+-#"))
    limit = sys.get_int_max_str_digits()
    return _Failure(f"{what} of {n} digits: longer than the {limit} digits an integer may have", pos,
                    (f"an integer of at most {limit} digits",))


@dataclass
class Header:
    """The HEADER section: every entity by upper-case name (FILE_DESCRIPTION, FILE_NAME, ...)."""

    entities: dict[str, list[Any]] = field(default_factory=dict)
    data_sections: list[list[Any]] = field(default_factory=list)
    text: str = ""  # the section verbatim, from HEADER to ENDSEC;
    #: edition 3: the DATA section openers verbatim (``DATA;``, ``DATA('a',('S'));``)
    data_section_texts: list[str] = field(default_factory=list)
    #: lenient mode repaired the opener's parameters (a bare schema name): its text is not valid
    #: Part 21, :func:`stepnc_graph.part21.format.format_value` of ``data_sections`` is
    data_section_repaired: list[bool] = field(default_factory=list)
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
        #: strict mode: (opened, typographic quote or -1, next instance, #id) of a string that ran on
        self._runaway: tuple[int, int, int, int | None] | None = None
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
        #: lenient: text that names no instance, kept (see UnreadableText)
        self.unreadable_texts: list[UnreadableText] = []
        self._stray = False  # the section being read was reopened for an instance after its ENDSEC;
        self._line = 1
        self._line_start = 0
        self._cursor = 0  # offset up to which _line/_line_start are exact
        self._pos = self._read_header()
        try:
            self._pos = self._read_reference_sections(self._pos)
        except _Failure as failure:
            raise self._syntax_error(failure, None) from None
        #: where the DATA sections begin: everything before is the HEADER, ANCHOR and REFERENCE
        #: sections (kept verbatim in ``header``)
        self.body_start = self._pos

    @property
    def ids(self) -> set[int]:
        """The ``#id``s of the instances read so far (unreadable ones included, later
        definitions of an ``#id`` not)."""
        return self._ids

    # -- positions ------------------------------------------------------------

    def position(self, offset: int) -> tuple[int, int]:
        """1-based (line, column) of ``offset``; incremental from the last offset asked for, either
        way, so that a diagnostic a little before the last one does not recount the file."""
        text = self.text
        if offset < self._cursor:
            n = text.count("\n", offset, self._cursor)
            if n:
                self._line -= n
                self._line_start = text.rfind("\n", 0, offset) + 1
        else:
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
        """``recoverable``: the error is in the DATA sections, where lenient reading goes on. An error
        after a string of the same instance that ran into the next instance is that string's: it is
        reported where the string opened (see :meth:`_string`)."""
        runaway = self._runaway
        if runaway is not None and runaway[3] == p21_id and runaway[0] < failure.pos:
            failure = self._runaway_failure(*runaway[:3])
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
        try:
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
        except ValueError:  # int() refuses an integer longer than sys.get_int_max_str_digits()
            if kind not in ("int", "ref"):  # pragma: no cover - nothing else raises ValueError here
                raise
            raise _too_long(tok, start, "a reference" if kind == "ref" else "an integer") from None

    def _bad_token(self, kind: str, tok: str, start: int, expected: tuple[str, ...]) -> _Failure:
        if kind == "bad" and tok == "'":
            return _Failure("string is never closed", start, ("'",))
        if kind == "bad" and tok == "/*":
            return _Failure("comment '/*' is never closed", start, ("*/",))
        return _Failure(f"expected {' or '.join(repr(e) for e in expected)}, found {show(tok)}", start, expected)

    def _runaway_failure(self, opened: int, curly: int, swallowed: int) -> _Failure:
        """A string that ran on into the next instance, told where it opened and what ended it."""
        next_line, _ = self.position(swallowed)
        cause = ""
        if curly >= 0:
            line, column = self.position(curly)
            cause = f"; the typographic quote (U+2019) at {line}:{column} probably ends it (--lenient reads it so)"
        return _Failure(f"the string opened here is not closed before the next instance (line {next_line}){cause}",
                        opened, ("'",))

    def _string(self, tok: str, start: int, end: int, p21_id: int | None) -> tuple[str, int]:
        """Decode a string token; in lenient mode repair a typographic closing quote. In strict mode
        a string that runs on into the next instance is remembered: the syntax error it causes
        further on is reported where the string opened (:meth:`_syntax_error`)."""
        if not self.lenient and "\n" in tok:
            first_break = tok.index("\n")
            found = _INSTANCE_START.search(tok, first_break)
            if found:
                curly = tok.find(_CURLY, 0, first_break)
                self._runaway = (start, start + curly if curly > 0 else -1, start + found.start(), p21_id)
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
            return Ref(_integer(tok[1:], start, "an instance name")), end
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
            if kind == "ref":
                _integer(tok[1:], start, "an instance name")  # the loader names the instance by it
            ukind, utok, ustart, uend = self._token(self._expect(end, "="))
            if ukind != "uri":
                raise _Failure(f"expected a resource <uri>, found {show(utok)}", ustart, ("<uri>",))
            self.header.references.append((tok, utok[1:-1]))
            pos = self._expect(uend, ";")

    def _section_start(self, pos: int) -> int | None:
        """After ``DATA;``/``DATA(...);`` return the offset; at the end of the file return None."""
        kind, tok, start, end = self._token(pos)
        if kind == "kw" and tok.upper() == "DATA":
            params: list[Any] = []
            first = len(self.diagnostics)
            if self._token(end)[1] == "(":
                params, end = self._params(end, None)
            repaired = len(self.diagnostics) > first
            try:
                end = self._expect(end, ";")
                opener = self.text[start:end]
            except _Failure:
                if not (self.lenient and self._statement_follows(end)):
                    raise
                self._diagnose("P21-MISSING-SEMICOLON", end, None, "';' missing after DATA; read as present")
                opener = self.text[start:end] + ";"
            self.header.data_sections.append(params)
            self.header.data_section_texts.append(opener)
            self.header.data_section_repaired.append(repaired)
            return end
        m = _END.match(self.text, start)
        if m is not None:
            after = m.end()
            while (sig := _SIGNATURE.match(self.text, after)) is not None:
                self.header.signatures.append(sig.group(1))
                after = sig.end()
            self._after_end(after)
            return None
        if self.lenient and self.text.startswith("END-ISO-10303-21", start):
            self._diagnose("P21-MISSING-SEMICOLON", start, None, "';' missing after END-ISO-10303-21; read as present")
            self._after_end(start + len("END-ISO-10303-21"))
            return None
        if kind == "eof" and self.lenient:
            if not self._truncated:
                self._diagnose("P21-END-MISSING", start, None,
                               "the file ends without 'END-ISO-10303-21;'; everything before it is loaded")
            return None
        raise _Failure(f"expected DATA or END-ISO-10303-21, found {show(tok)}" if tok else
                       "expected DATA or END-ISO-10303-21, found end of file", start,
                       ("DATA", "END-ISO-10303-21;"))

    def _after_end(self, pos: int) -> None:
        """Nothing but white space and comments may follow the end marker and its signatures
        (ISO 10303-21:2016, 13): anything else is an error; lenient, kept as text."""
        kind, tok, start, _ = self._token(pos)
        if kind == "eof":
            return
        failure = _Failure(f"text after END-ISO-10303-21;, found {show(tok)}", start, ("end of file",))
        if not self.lenient:
            raise self._syntax_error(failure, None, recoverable=True)
        self._keep_text(start, len(self.text), failure.message, max(len(self.header.data_sections) - 1, 0))

    def _keep_text(self, start: int, end: int, message: str, section: int) -> None:
        """Lenient: report the text ``start:end`` (up to its last non-blank character) that names
        no instance, and keep it (:class:`UnreadableText`)."""
        end = start + len(self.text[start:end].rstrip())
        line, column = self.position(start)
        self.diagnostics.append(Diagnostic.make("P21-SYNTAX", self.filename, line, column, None,
                                                f"{message}; kept as text"))
        self.unreadable_texts.append(UnreadableText(start, end, line, column, section, message))

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

        Lenient: text where a section should start is kept (and reported) up to the
        next instance boundary; an instance found there is read into the preceding
        DATA section (which the next ``END-ISO-10303-21;``, ``DATA`` or ``ENDSEC;`` closes).
        """
        while True:
            try:
                return self._section_start(pos)
            except _Failure as failure:
                if not self.lenient:
                    raise self._syntax_error(failure, None, recoverable=True) from None
                kind, tok, start, end = self._token(pos)  # the statement that failed
                message = self._where(failure, start)
            if kind == "ref" and self._token(end)[1] == "=":
                self._diagnose("P21-OUTSIDE-SECTION", start, self._name(tok),
                               "instance outside a DATA section; read into the preceding one")
                if not self.header.data_sections:
                    self.header.data_sections.append([])
                    self.header.data_section_texts.append("DATA;")
                    self.header.data_section_repaired.append(False)
                self._stray = True
                return start
            section = max(len(self.header.data_sections) - 1, 0)
            boundary = self._boundary(start)
            if boundary is None:
                self._keep_text(start, len(self.text), message, section)
                self._truncated = True  # reported: no end-marker warning on top
                return None
            self._keep_text(start, boundary[0], message, section)
            pos = boundary[1]

    def _statement_follows(self, pos: int) -> bool:
        """Whether an instance (``#12=``) or ``ENDSEC`` comes next: a ``;`` before it was left out."""
        kind, tok, _, end = self._token(pos)
        return (kind == "ref" and self._token(end)[1] == "=") or (kind == "kw" and tok.upper() == "ENDSEC")

    def _name(self, tok: str) -> int | None:
        """The #id of an instance name token; None when it is too long for ``int()``."""
        try:
            return int(tok[1:])
        except ValueError:
            return None

    def _data_section(self, pos: int, index: int) -> Generator[Instance, None, int]:
        stray, self._stray = self._stray, False
        while True:
            kind, tok, start, end = self._token(pos)
            if kind == "kw":
                upper = tok.upper()
                if upper == "ENDSEC":
                    return self._end_of_section(end)
                if self.lenient and self._section_closer(upper, start, end):
                    if not stray:
                        self._diagnose("P21-ENDSEC-MISSING", start, None,
                                       f"'ENDSEC;' missing before {show(tok)}; read as present")
                    return start
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
                if not self._truncated and not stray:  # a reopened section had its ENDSEC
                    self._truncate(start, None)
                return start
            p21_id = None
            if kind == "ref":
                try:
                    p21_id = int(tok[1:])
                except ValueError:  # longer than int() reads: reported below
                    pass
            first = len(self.diagnostics)
            try:
                if p21_id is None:
                    if kind == "ref":
                        raise _too_long(tok, start, "an instance name")
                    raise self._bad_token(kind, tok, start, ("#id", "ENDSEC"))
                instance, pos = self._instance(p21_id, start, end)
            except _Failure as failure:
                if not self.lenient:
                    raise self._syntax_error(failure, p21_id, recoverable=True) from None
                del self.diagnostics[first:]  # repairs inside what is now kept as text
                broken, pos = self._recover(failure, p21_id, start, index)
                if broken is not None:
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

    def _section_closer(self, upper: str, start: int, end: int) -> bool:
        """Whether the keyword ``upper`` at ``start`` opens the next DATA section or the end
        marker: a DATA section left without its ``ENDSEC;``."""
        if upper == "DATA":
            return self._token(end)[1] in (";", "(")
        return upper == "END" and self.text.startswith("END-ISO-10303-21", start)

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

    def _recover(self, failure: _Failure, p21_id: int | None, start: int,
                 section: int) -> tuple[Instance | None, int]:
        """Report what could not be read and keep its text: as an unreadable instance (when it
        has an ``#id`` not defined before), as a later definition of its ``#id``, or as text
        that names no instance. Returns the instance and the offset where reading goes on."""
        boundary = self._boundary(start)
        end, resume = boundary if boundary is not None else (len(self.text), len(self.text))
        if boundary is None:  # nothing readable follows: the file stops inside this statement
            self._truncate(start, p21_id)
        if p21_id is None:
            if boundary is None:
                end = start + len(self.text[start:end].rstrip())
                line, column = self.position(start)
                self.unreadable_texts.append(UnreadableText(start, end, line, column, section, failure.message))
            else:
                self._keep_text(start, end, self._where(failure, start), section)
            return None, resume
        self.defined += 1
        if boundary is not None:
            kept = "; kept as text" if p21_id not in self._ids else "; not loaded"
            self._diagnose("P21-SYNTAX", start, p21_id, f"{self._where(failure, start)}{kept}")
        end = start + len(self.text[start:end].rstrip())
        if p21_id in self._ids:
            self.duplicate_texts.append((p21_id, start, end, self.position(start)[0]))
            return None, resume
        self._ids.add(p21_id)
        named = _ENTITY_NAME.match(self.text, start)
        line, column = self.position(start)
        return Instance(p21_id, named.group(1).upper() if named else None, [], line, column, start, end,
                        section=section, unreadable=failure.message), resume

    def _where(self, failure: _Failure, start: int) -> str:
        """The failure's message, with its position when that is not the statement's start."""
        if failure.pos == start:
            return failure.message
        line, column = self.position(failure.pos)
        return f"{failure.message} at line {line}, column {column}"

    def _boundary(self, start: int) -> tuple[int, int] | None:
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
            kind, tok, tstart, tend = self._token(pos)
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
            elif tstart > start and self._statement_start(kind, tok, tstart, tend, depth, previous):
                return start + len(self.text[start:tstart].rstrip()), tstart
            previous = tok
            pos = tend

    def _statement_start(self, kind: str, tok: str, start: int, end: int, depth: int, previous: str) -> bool:
        """Whether the token (``start:end``) starts a statement: an instance ``#12=``, ``ENDSEC``,
        ``END-ISO-10303-21``, ``DATA;``, or ``DATA(`` outside parentheses and not after ``=``
        (where it would be an entity named DATA)."""
        if kind == "ref":
            return self._token(end)[1] == "="
        if kind != "kw":
            return False
        upper = tok.upper()
        if upper == "ENDSEC":
            return True
        if upper == "END":
            return self.text.startswith("END-ISO-10303-21", start)
        if upper == "DATA":
            follows = self._token(end)[1]
            return follows == ";" or (follows == "(" and depth == 0 and previous != "=")
        return False


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
    limit = sys.get_int_max_str_digits() or len(text)  # a longer one is no name the reader accepts
    return {int(x) for x in _DEFINITION.findall(text) if len(x) <= limit}


_ONE_INSTANCE = ("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('','',(''),(''),'','','');\n"
                 "FILE_SCHEMA(('ANY'));\nENDSEC;\nDATA;\n{}\nENDSEC;\nEND-ISO-10303-21;\n")


def read_instance(text: str, filename: str = "<string>") -> Instance:
    """The one instance ``text`` defines (``#12=NAME(...);``), read strictly.

    The Part 21 writer writes a raw instance's kept text as it is; a graph edited by hand (or
    imported from JSON-LD) could hold any string there, so the writer reads it back first:
    :class:`Part21SyntaxError` unless the text is exactly one instance and nothing else.
    """
    reader = Part21Reader(_ONE_INSTANCE.format(text), filename)
    found = list(reader.instances())
    if len(found) != 1 or reader.unreadable_texts:
        raise Part21SyntaxError(f"the text {text[:80]!r} is not exactly one instance", filename, 1, 1, "")
    return found[0]


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
