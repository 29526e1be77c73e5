"""Parameter lists of the Part 21 reader: ``( value, ... )`` to Python values, strings decoded
(lenient: a typographic closing quote repaired). The hot path of every load: one loop over the
tokens with an explicit stack, the regex match bound to a local."""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any

from stepnc_graph.core.errors import show
from stepnc_graph.part21.strings import StringDecodeError, decode
from stepnc_graph.part21.tokens import _CURLY, _INSTANCE_START, TOKEN, _Failure, _too_long, bad_token
from stepnc_graph.part21.values import DERIVED, UNSET, Binary, Enum, Name, Ref, Typed

if TYPE_CHECKING:
    from stepnc_graph.part21.reader import Part21Reader

_MAX_DEPTH = 200  # nested lists; deeper input is rejected, not a RecursionError or hang

#: a value (reference, string, number, enumeration, ``$``, ``*``) and the ``,`` or ``)`` right after
#: it, as :data:`TOKEN` reads them: one match where the token loop makes two, and the value's kind
#: told by its first character (a replicated 100k-instance program: the parse 2.23 -> 1.5 CPU-s)
_VALUE_THEN = re.compile(r"(#[0-9]+|'[^']*(?:''[^']*)*'|[+-]?[0-9]+(?:\.[0-9]*(?:[Ee][+-]?[0-9]+)?)?"
                         r"|\.[A-Za-z_][A-Za-z0-9_]*\.|[$*])([,)])")


def parse_params(r: Part21Reader, pos: int, p21_id: int | None) -> tuple[list[Any], int]:
    """Parse ``( value, ... )`` starting at the ``(`` at or after ``pos``.

    Iterative with an explicit stack (bounded depth), so deep nesting in
    damaged input is an error, never a RecursionError.
    """
    match = TOKEN.match
    value_then = _VALUE_THEN.match
    text = r.text
    if text.startswith("(", pos):  # no whitespace or comment before it: the usual case
        kind, tok, start, pos = "p", "(", pos, pos + 1
    else:
        kind, tok, start, pos = r._token(pos)
    if tok != "(":
        raise _Failure(f"expected '(', found {show(tok)}" if tok else "expected '(', found end of file", start, ("(",))
    stack: list[tuple[list[Any], str | None]] = []
    current: list[Any] = []
    typed: str | None = None
    expect_value = True
    unclosed = r._unclosed_from
    try:
        while True:
            if expect_value and (m := value_then(text, pos)) is not None:
                # the common case, a value and the ',' or ')' right after it, in one match (the
                # general loop below takes anything else: whitespace, comments, nested and typed
                # values, a string over lines, errors)
                tok, sep = m.groups()
                first = tok[0]
                start = pos
                if first == "#":
                    kind = "ref"
                    current.append(Ref(tok[1:]))
                elif first == "'":
                    if "\n" in tok:  # may be a string run on (repaired, or reported where it opened)
                        m = None
                    else:
                        current.append(_decoded(tok, pos))
                elif first == ".":
                    current.append(Enum(tok[1:-1].upper()))
                elif first == "$":
                    current.append(UNSET)
                elif first == "*":
                    current.append(DERIVED)
                elif "." in tok:
                    current.append(float(tok))
                else:
                    kind = "int"
                    current.append(int(tok))
                if m is not None:
                    pos = m.end()
                    if sep == ",":
                        continue
                    finished, finished_typed = current, typed
                    if not stack:
                        return finished, pos
                    current, typed = _closed(finished, finished_typed, stack, pos - 1)
                    expect_value = False
                    continue
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
                    value, pos = read_string(r, tok, start, pos, p21_id)
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
                    nkind, ntok, nstart, nend = r._token(pos)
                    if ntok == "(":
                        if len(stack) >= _MAX_DEPTH:
                            raise _Failure(f"lists nested deeper than {_MAX_DEPTH}", start)
                        stack.append((current, typed))
                        current, typed, pos = [], tok.upper(), nend
                        continue
                    if not r.lenient:
                        raise _Failure(f"expected a parameter value, found {show(tok)} (enumeration values are "
                                       f"written .{tok.upper()}.)", start, ("value",))
                    r._diagnose("P21-BARE-ENUM", start, p21_id, f"{show(tok)} read as .{tok.upper()[:40]}.")
                    current.append(Enum(tok.upper()))
                elif kind == "bin":
                    current.append(Binary(tok[1:-1]))
                elif kind == "name":
                    current.append(Name(tok))
                else:
                    raise bad_token(kind, tok, start, ("value",))
                expect_value = False
            else:
                if tok == ",":
                    expect_value = True
                elif tok == ")":
                    finished, finished_typed = current, typed
                    if not stack:
                        return finished, pos
                    current, typed = _closed(finished, finished_typed, stack, start)
                else:
                    raise bad_token(kind or "bad", tok, start, (",", ")"))
    except ValueError:  # int() refuses an integer longer than sys.get_int_max_str_digits()
        if kind not in ("int", "ref"):  # pragma: no cover - nothing else raises ValueError here
            raise
        raise _too_long(tok, start, "a reference" if kind == "ref" else "an integer") from None


def _closed(finished: list[Any], finished_typed: str | None, stack: list[tuple[list[Any], str | None]],
            at: int) -> tuple[list[Any], str | None]:
    """The list around the one just closed (``finished``, or the typed parameter it is the
    argument of) with it appended, and that list's own type: what the parse goes on with."""
    current, typed = stack.pop()
    if finished_typed is not None:
        if len(finished) != 1:
            raise _Failure(f"typed parameter {finished_typed} needs exactly one value", at)
        current.append(Typed(finished_typed, finished[0]))
    else:
        current.append(finished)
    return current, typed


def runaway_failure(r: Part21Reader, opened: int, curly: int, swallowed: int) -> _Failure:
    """A string that ran on into the next instance, told where it opened and what ended it."""
    next_line, _ = r.position(swallowed)
    cause = ""
    if curly >= 0:
        line, column = r.position(curly)
        cause = f"; the typographic quote (U+2019) at {line}:{column} probably ends it (--lenient reads it so)"
    return _Failure(f"the string opened here is not closed before the next instance (line {next_line}){cause}",
                    opened, ("'",))


def _decoded(tok: str, start: int) -> str:
    """The string token ``tok`` at ``start`` decoded (one on a single line: nothing to repair)."""
    try:
        return decode(tok[1:-1])
    except StringDecodeError as e:
        raise _Failure(str(e), start + 1 + e.offset) from None


def read_string(r: Part21Reader, tok: str, start: int, end: int, p21_id: int | None) -> tuple[str, int]:
    """Decode a string token; in lenient mode repair a typographic closing quote. In strict mode
    a string that runs on into the next instance is remembered: the syntax error it causes
    further on is reported where the string opened (:meth:`Part21Reader._syntax_error`)."""
    if not r.lenient and "\n" in tok:
        first_break = tok.index("\n")
        found = _INSTANCE_START.search(tok, first_break)
        if found:
            curly = tok.find(_CURLY, 0, first_break)
            r._runaway = (start, start + curly if curly > 0 else -1, start + found.start(), p21_id)
    if r.lenient and "\n" in tok:
        first_break = tok.index("\n")
        k = tok.find(_CURLY, 0, first_break)
        if k > 0 and _INSTANCE_START.search(tok, first_break):
            r._diagnose("P21-CURLY-QUOTE", start + k, p21_id,
                        "string closed by a typographic quote (U+2019); read as closed there")
            tok, end = tok[:k] + "'", start + k + 1
    try:
        return decode(tok[1:-1]), end
    except StringDecodeError as e:
        raise _Failure(str(e), start + 1 + e.offset) from None
