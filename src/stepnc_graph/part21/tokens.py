"""The lexical layer of the Part 21 reader: one compiled regular expression that tokenizes,
the patterns that find statement boundaries, and the syntax failure the parser raises (a
:class:`_Failure` is turned into a positioned :class:`~stepnc_graph.part21.diagnostics.Part21SyntaxError`
by the reader, which knows the file's lines)."""

from __future__ import annotations

import re
import sys

from stepnc_graph.core.errors import show

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
_INSTANCE_START = re.compile(r"#[0-9]+[ \t\r\n]*=")
_CURLY = "\u2019"


class _Failure(Exception):
    """A syntax error at offset ``pos``, with what was expected there; the reader turns it into
    a :class:`~stepnc_graph.part21.diagnostics.Part21SyntaxError` with line and column (or, lenient,
    recovers at the next statement)."""

    def __init__(self, message: str, pos: int, expected: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.message = message
        self.pos = pos
        self.expected = expected


def _integer(digits: str, pos: int, what: str) -> int:
    """``int(digits)``, or the syntax error for an integer longer than the interpreter reads
    (``sys.get_int_max_str_digits()``, 4,300 by default: ``int()`` refuses more)."""
    try:
        return int(digits)
    except ValueError:
        raise _too_long(digits, pos, what) from None


def _too_long(digits: str, pos: int, what: str) -> _Failure:
    """The failure for an integer ``digits`` too long for ``int()`` (see :func:`_integer`)."""
    n = len(digits.lstrip("+-#"))
    limit = sys.get_int_max_str_digits()
    return _Failure(f"{what} of {n} digits: longer than the {limit} digits an integer may have", pos,
                    (f"an integer of at most {limit} digits",))


def bad_token(kind: str, tok: str, start: int, expected: tuple[str, ...]) -> _Failure:
    """The failure for an unexpected token: a lone quote or ``/*`` is a string or comment never closed."""
    if kind == "bad" and tok == "'":
        return _Failure("string is never closed", start, ("'",))
    if kind == "bad" and tok == "/*":
        return _Failure("comment '/*' is never closed", start, ("*/",))
    return _Failure(f"expected {' or '.join(repr(e) for e in expected)}, found {show(tok)}", start, expected)
