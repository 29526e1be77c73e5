"""Reading a JSON-LD file as JSON, strictly (:mod:`stepnc_graph.loading.jsonld`): a key given twice,
a number an ``xsd:double`` cannot hold, nesting deeper than :data:`MAX_DEPTH` are refused where JSON
would keep one, round or crash; :class:`JsonLdError` and how its messages show the document's text.
"""

from __future__ import annotations

import json
import math
import re
import stat
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Any


from stepnc_graph.loading.common import SourceError


#: arrays and objects nested deeper than this are refused (an export nests about 15 levels)
MAX_DEPTH = 500
#: the longest ``@id`` read (characters): every statement about a node -- about every node, for
#: the graph's own ``@id`` -- repeats its IRI, so a document of 1 MB whose ``@id`` was 1 MB took
#: 60 CPU-s and gigabytes to load (found by the fuzz harness); real IRIs are far shorter (HTTP
#: servers commonly refuse request lines over 8 KiB)
MAX_IRI = 16_384
#: an integer written with at most this many digits (no fraction, no exponent) is an exact
#: ``xsd:integer``; a longer one is read by JSON-LD as an ``xsd:double``
INTEGER_DIGITS = 20
#: the keywords of JSON-LD 1.1; any other key of the form ``@letters`` is ignored by a processor
KEYWORDS = frozenset({
    "@base", "@container", "@context", "@direction", "@graph", "@id", "@import", "@included", "@index", "@json",
    "@language", "@list", "@nest", "@none", "@prefix", "@propagate", "@protected", "@reverse", "@set", "@type",
    "@value", "@version", "@vocab"})
KEYWORD_FORM = re.compile(r"@[A-Za-z]+")
#: characters no IRI may hold (RFC 3987: controls, space, and <>"{}|^`\)
NOT_IN_IRI = re.compile(r'[\x00-\x20<>"{}|^`\\\x7f-\x9f]')
BAD_PERCENT = re.compile(r"%(?![0-9A-Fa-f]{2})")
SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*:")
#: blank node labels written as they are (a subset of N-Triples'); others are given a new one
BLANK_LABEL = re.compile(r"[A-Za-z0-9_](?:[A-Za-z0-9_.-]*[A-Za-z0-9_-])?")


class JsonLdError(SourceError):
    """A JSON-LD input that cannot be loaded: not JSON, a remote context, an invalid IRI, not
    one program graph, ... ``pointer``: where in the document (RFC 6901), when it is known."""

    def __init__(self, message: str, file: str, line: int | None = None, column: int | None = None,
                 pointer: str | None = None) -> None:
        where = f"{file}:{line}:{column}" if line is not None else file
        if pointer is not None:
            where += f" at {show_pointer(pointer)}" if pointer else " at the top level"
        super().__init__(f"{where}: {message}")
        self.file, self.line, self.column, self.message, self.pointer = file, line, column, message, pointer

    def asdict(self) -> dict[str, Any]:
        return {"type": "JsonLdError", "file": self.file, "line": self.line, "column": self.column,
                "pointer": self.pointer, "message": self.message}


# -- how a message shows the document's text ------------------------------------------------------


def printable(text: str) -> str:
    """``text`` with control characters (and lone surrogates) written as JSON escapes ``\\u0000``."""
    return "".join(c if " " <= c < "\x7f" or ("\xa0" <= c and not "\ud800" <= c <= "\udfff") else f"\\u{ord(c):04x}"
                   for c in text)


def quote(text: str, longest: int = 200) -> str:
    """``text`` quoted for a message; a long one is shortened, saying how long it is."""
    shown = printable(text if len(text) <= longest else text[:longest - 40])
    return f'"{shown}"' if len(text) <= longest else f'"{shown}..." ({len(text):,} characters)'


def show_pointer(pointer: str) -> str:
    """A JSON pointer for a message: printable, and a very long one shortened in its middle."""
    shown = printable(pointer)
    return shown if len(shown) <= 200 else shown[:120] + "..." + shown[-60:]


def char_name(c: str) -> str:
    """How a message names one character."""
    names = {" ": "a space", "\t": "a tab, U+0009", "\n": "a line break, U+000A", "\r": "a carriage return, U+000D",
             "\x00": "a NUL character, U+0000"}
    if c in names:
        return names[c]
    return f"the control character U+{ord(c):04X}" if c < " " or "\x7f" <= c <= "\x9f" else f"'{c}'"


# -- reading the JSON -----------------------------------------------------------------------------


class Refused:
    """Put by the JSON reader where a value is that JSON-LD could not keep as written; the walk
    (:func:`local_contexts`) reports it with its JSON pointer."""

    __slots__ = ("message",)

    def __init__(self, message: str) -> None:
        self.message = message


def _json_integer(text: str) -> Any:
    """A JSON integer: exact up to :data:`INTEGER_DIGITS` digits, else what JSON-LD makes of it (a double)."""
    if len(text) - (text[0] == "-") <= INTEGER_DIGITS:
        return int(text)
    return _json_double(text)


def _json_double(text: str) -> Any:
    """A JSON number JSON-LD reads as an ``xsd:double``: the float, when it is the number written
    (its shortest form gives the number back); else :class:`Refused` -- the store would keep
    infinity, zero or a rounded value instead (Python's own reader would fail on 4,300 digits)."""
    value = float(text)  # no digit limit; a number beyond the range is inf
    if math.isfinite(value) and repr(value) == text:
        return value
    try:
        same = math.isfinite(value) and Decimal(repr(value)) == Decimal(text)
    except InvalidOperation:  # an exponent beyond what a decimal holds
        same = False
    if same:
        return value
    why = ("is beyond the range of a double" if not math.isfinite(value) else
           "is closer to zero than a double can be" if value == 0 else "has more significant digits than a double keeps")
    return Refused(f"the number {quote(text, 60)} would become an xsd:double (JSON-LD reads a number with a "
                    f"fraction, an exponent or more than {INTEGER_DIGITS} digits as one), and it {why}: write "
                    'it as a string with its datatype, e.g. {"@value": "...", "@type": "xsd:decimal"}')


def _json_constant(text: str) -> Refused:
    return Refused(f"{text} is not a JSON number (JSON has no NaN or infinity); write it as "
                    f'{{"@value": "{"INF" if "Infinity" in text else "NaN"}", "@type": "xsd:double"}}')


def _json_object(pairs: list[tuple[str, Any]]) -> Any:
    """A JSON object; :class:`Refused` when it gives a key twice (JSON would keep only the last)."""
    out = dict(pairs)
    if len(out) == len(pairs):
        return out
    seen: set[str] = set()
    twice = next(k for k, _ in pairs if k in seen or seen.add(k))  # type: ignore[func-returns-value]
    return Refused(f"this object gives the key {quote(twice)} twice; JSON keeps only one of them, so the "
                    "other would be lost")


def read_bytes(path: Path) -> bytes:
    """The file's bytes; devices and directories are refused (they would never end)."""
    mode = path.stat().st_mode
    if stat.S_ISDIR(mode):
        raise IsADirectoryError(f"{path}: a directory, not a JSON-LD file")
    if not (stat.S_ISREG(mode) or stat.S_ISFIFO(mode)):
        raise OSError(f"{path}: not a regular file (a device or socket); give a JSON-LD file")
    return path.read_bytes()


def parse_json(raw: bytes, name: str) -> Any:
    """The JSON value of ``raw``; :class:`JsonLdError` with line and column where it is not JSON.
    Values JSON-LD could not keep are :class:`Refused` in it (see :func:`local_contexts`)."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw.count(b"\n", 0, e.start) + 1
        column = e.start - (raw.rfind(b"\n", 0, e.start) + 1) + 1
        raise JsonLdError(f"not UTF-8 (byte 0x{raw[e.start]:02X}); JSON-LD is UTF-8", name, line, column) from None
    try:
        return json.loads(text, object_pairs_hook=_json_object, parse_int=_json_integer, parse_float=_json_double,
                          parse_constant=_json_constant)
    except json.JSONDecodeError as e:
        raise JsonLdError(f"not JSON: {e.msg}", name, e.lineno, e.colno) from None
    except RecursionError:
        raise JsonLdError(too_deep(), name) from None


def too_deep() -> str:
    return (f"arrays and objects are nested deeper than {MAX_DEPTH} levels; a program graph nests about 15 "
            "(refused so that reading it stays bounded)")


# -- the walk: contexts, keys, values -------------------------------------------------------------

#: where a value is: None (the top), or (where its container is, its key or index)
JsonPath = tuple[Any, str | int] | None


def pointer(path: JsonPath) -> str:
    """The RFC 6901 JSON pointer of ``path``."""
    tokens: list[str] = []
    while path is not None:
        path, token = path
        tokens.append(str(token).replace("~", "~0").replace("/", "~1"))
    return "".join("/" + t for t in reversed(tokens))
