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
from pathlib import Path

from stepnc_graph.core.errors import show
from stepnc_graph.part21.diagnostics import Diagnostic, Part21SyntaxError
from stepnc_graph.part21.model import Header, Instance, UnreadableText
from stepnc_graph.part21.parameters import parse_params, runaway_failure
from stepnc_graph.part21.recovery import keep_text, recover, statement_end, truncate, where
from stepnc_graph.part21.sections import read_header, read_reference_sections, section_start
from stepnc_graph.part21.source import read_text_source
from stepnc_graph.part21.tokens import _INSTANCE_START, TOKEN, _Failure, _too_long, bad_token

__all__ = ["TOKEN", "Header", "Instance", "Part21Reader", "UnreadableText", "defined_ids", "read_file",
           "read_instance", "read_text"]

_DEFINITION = re.compile(r"#([0-9]+)[ \t\r\n]*=")
#: ``=NAME`` right after an instance's ``#id``, as TOKEN reads the name (see Part21Reader._instance)
_HEAD = re.compile(r"=(!?[A-Za-z_][A-Za-z0-9_]*)")
#: an ``#id`` after plain whitespace, as TOKEN reads it (see Part21Reader._data_section)
_NEXT_REF = re.compile(r"[ \t\r\n]*(#[0-9]+)")
_COMMENT = re.compile(r"/\*.*?\*/", re.S)


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
        self._pos = read_header(self, )
        try:
            self._pos = read_reference_sections(self, self._pos)
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
        reported where the string opened (see :func:`~stepnc_graph.part21.parameters.read_string`)."""
        runaway = self._runaway
        if runaway is not None and runaway[3] == p21_id and runaway[0] < failure.pos:
            failure = runaway_failure(self, *runaway[:3])
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
                return section_start(self, pos)
            except _Failure as failure:
                if not self.lenient:
                    raise self._syntax_error(failure, None, recoverable=True) from None
                kind, tok, start, end = self._token(pos)  # the statement that failed
                message = where(self, failure, start)
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
            boundary = statement_end(self, start)
            if boundary is None:
                keep_text(self, start, len(self.text), message, section)
                self._truncated = True  # reported: no end-marker warning on top
                return None
            keep_text(self, start, boundary[0], message, section)
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
        next_ref = _NEXT_REF.match
        while True:
            ref = next_ref(self.text, pos)
            if ref is not None:  # the next instance's #id after plain whitespace, as TOKEN reads it
                kind, tok, start, end = "ref", ref.group(1), ref.start(1), ref.end()
            else:
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
                    truncate(self, start, None)
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
                    raise bad_token(kind, tok, start, ("#id", "ENDSEC"))
                instance, pos = self._instance(p21_id, start, end)
            except _Failure as failure:
                if not self.lenient:
                    raise self._syntax_error(failure, p21_id, recoverable=True) from None
                del self.diagnostics[first:]  # repairs inside what is now kept as text
                broken, pos = recover(self, failure, p21_id, start, index)
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

    def _instance(self, p21_id: int, start: int, pos: int) -> tuple[Instance, int]:
        head = _HEAD.match(self.text, pos)
        if head is not None:  # '=' and the entity name with nothing between: one match, not two tokens
            kind, tok, tend = "kw", head.group(1), head.end()
        else:
            pos = self._expect(pos, "=")
            kind, tok, tstart, tend = self._token(pos)
        if kind == "kw":
            params, pos = parse_params(self, tend, p21_id)
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
                part_params, pos = parse_params(self, tend, p21_id)
                parts.append((tok.upper(), part_params))
            if not parts:
                raise _Failure("empty complex instance", tstart, ("entity name",))
        else:
            raise _Failure(f"expected an entity name or '(', found {show(tok)}", tstart, ("entity name", "("))
        end = pos + 1 if self.text.startswith(";", pos) else self._instance_end(pos, p21_id)
        line, column = self.position(start)
        return Instance(p21_id, name, params, line, column, start, end, parts), end

    def _instance_end(self, pos: int, p21_id: int) -> int:
        """Where the instance whose parameters end at ``pos`` ends: after its ``;`` (lenient: a
        missing one is reported and assumed before the next instance, ``ENDSEC`` or the end)."""
        kind, tok, tstart, tend = self._token(pos)
        if tok == ";":
            return tend
        if self.lenient and (kind == "eof" or (kind == "ref" and _INSTANCE_START.match(self.text, tstart))
                             or (kind == "kw" and tok.upper() == "ENDSEC")):
            self._diagnose("P21-MISSING-SEMICOLON", pos, p21_id, "';' missing after the instance; read as present")
            return pos
        raise _Failure(f"expected ';', found {show(tok)}" if tok else "expected ';', found end of file", tstart,
                       (";",))





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
