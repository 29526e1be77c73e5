"""Load a JSON-LD document of a program graph (what ``export --format jsonld`` wrote, maybe
edited by a PLM system) as that program's named graph, so that the Part 21 export gives the
program back.

**No network, no files, ever.** A JSON-LD processor loads every context a document names
by IRI (``"@context": "https://..."``, ``@import``, a scoped context, at any depth of a
context array), which would let a document make stepnc-graph open connections, read local
files, or load term definitions that change what the data means. Two things stop it:

* the processor has no way to load a document: it is Oxigraph's (``pyoxigraph``, a
  dependency already), whose Python binding gives its JSON-LD parser no document loader, so a
  context named by IRI is an error in the processor itself, never a request;
* before the processor sees the document, a walk over all of it (:func:`local_contexts`)
  puts the installed ``ontology/context.jsonld`` where the shipped context's IRI
  (:data:`~stepnc_graph.core.naming.CONTEXT_IRI`) is named, and refuses any other IRI -- in a
  document, node, type- or property-scoped context, a nested array, ``@import`` -- with the
  JSON pointer of where it is.

**Nothing dropped.** JSON-LD silently drops what it cannot turn into RDF: a node whose
``@id`` is not a valid IRI, a key the context does not define, a key that looks like a
keyword, a bad language tag. The document is therefore read twice by the processor: as
JSON-LD says, and leniently (invalid IRIs kept). When the two differ, the load is refused,
naming each invalid value and where it is. JSON reading refuses a key given twice in one
object (JSON keeps the last), a number JSON-LD would turn into an ``xsd:double`` that cannot
hold it, nesting deeper than :data:`MAX_DEPTH` and an ``@id`` longer than :data:`MAX_IRI`.
Messages speak of the document (its JSON pointers, its values), not of the code that read it.

**Which graph.** The document names its graph (the top-level ``@id`` of an
export); it is loaded as that graph, unless ``--base-iri`` gives another, in
which case the document's IRIs under its graph move under the new one. A
document without a named graph is loaded as the graph its file name gives.

**What is replaced.** The graph's load metadata describes the load that wrote
it, as for a Part 21 file: ``dcterms:source``, ``prov:hadPrimarySource``,
``p21:byteSize``/``p21:sha256`` (of the JSON-LD file), the counts,
``prov:generatedAtTime`` and the load activity are those of this load; the
program the document was exported from stays visible as ``prov:wasDerivedFrom``
its primary source. The ``its_id`` aliases are recomputed from the data (a PLM
system may have renamed a workingstep). Everything else -- instances, HEADER
text, edition-3 sections, triples a PLM system added -- is stored as the
document says.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import stat
import time
from collections import defaultdict
from collections.abc import Iterator
from functools import lru_cache
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.version import __version__
from stepnc_graph.loading.common import DCT, PROV, RDFS, LoadResult, Progress, load_time
from stepnc_graph.mapping.editions import EDITIONS, edition_plans
from stepnc_graph.mapping.plans import Plans, iso14649_plans
from stepnc_graph.core.naming import CONTEXT_IRI, P21_NS, TOOL_IRI, alias_iri, instance_prefix
from stepnc_graph.part21.diagnostics import Diagnostic
from stepnc_graph.loading.common import Source, SourceError
from stepnc_graph.store import Store

RDF_TYPE = "http://www.w3.org/1999/02/22-rdf-syntax-ns#type"
XSD = "http://www.w3.org/2001/XMLSchema#"
OWL_SAME_AS = "http://www.w3.org/2002/07/owl#sameAs"
#: what the graph says about its load: replaced by this load's values
LOAD_PREDICATES = frozenset({
    DCT + "source", PROV + "hadPrimarySource", P21_NS + "byteSize", P21_NS + "sha256", P21_NS + "instanceCount",
    P21_NS + "rawInstanceCount", P21_NS + "diagnosticCount", PROV + "generatedAtTime", PROV + "wasGeneratedBy"})
CHUNK_TRIPLES = 20000
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
_KEYWORD_FORM = re.compile(r"@[A-Za-z]+")
#: characters no IRI may hold (RFC 3987: controls, space, and <>"{}|^`\)
_NOT_IN_IRI = re.compile(r'[\x00-\x20<>"{}|^`\\\x7f-\x9f]')
_BAD_PERCENT = re.compile(r"%(?![0-9A-Fa-f]{2})")
_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*:")
#: blank node labels written as they are (a subset of N-Triples'); others are given a new one
_BLANK_LABEL = re.compile(r"[A-Za-z0-9_](?:[A-Za-z0-9_.-]*[A-Za-z0-9_-])?")
#: the p21: properties the Part 21 writer reads as whole numbers: (how a message names them)
_NUMBERED = {P21_NS + "id": ("p21:id", "instance number"), P21_NS + "line": ("p21:line", "line number"),
             P21_NS + "sectionIndex": ("p21:sectionIndex", "section number")}
_WHOLE = re.compile(r"[0-9]{1,18}")
#: how many invalid values one message names
SHOWN = 5


class JsonLdError(SourceError):
    """A JSON-LD input that cannot be loaded: not JSON, a remote context, an invalid IRI, not
    one program graph, ... ``pointer``: where in the document (RFC 6901), when it is known."""

    def __init__(self, message: str, file: str, line: int | None = None, column: int | None = None,
                 pointer: str | None = None) -> None:
        where = f"{file}:{line}:{column}" if line is not None else file
        if pointer is not None:
            where += f" at {_show_pointer(pointer)}" if pointer else " at the top level"
        super().__init__(f"{where}: {message}")
        self.file, self.line, self.column, self.message, self.pointer = file, line, column, message, pointer

    def asdict(self) -> dict[str, Any]:
        return {"type": "JsonLdError", "file": self.file, "line": self.line, "column": self.column,
                "pointer": self.pointer, "message": self.message}


# -- how a message shows the document's text ------------------------------------------------------


def _printable(text: str) -> str:
    """``text`` with control characters (and lone surrogates) written as JSON escapes ``\\u0000``."""
    return "".join(c if " " <= c < "\x7f" or ("\xa0" <= c and not "\ud800" <= c <= "\udfff") else f"\\u{ord(c):04x}"
                   for c in text)


def _quote(text: str, longest: int = 200) -> str:
    """``text`` quoted for a message; a long one is shortened, saying how long it is."""
    shown = _printable(text if len(text) <= longest else text[:longest - 40])
    return f'"{shown}"' if len(text) <= longest else f'"{shown}..." ({len(text):,} characters)'


def _show_pointer(pointer: str) -> str:
    """A JSON pointer for a message: printable, and a very long one shortened in its middle."""
    shown = _printable(pointer)
    return shown if len(shown) <= 200 else shown[:120] + "..." + shown[-60:]


def _char(c: str) -> str:
    """How a message names one character."""
    names = {" ": "a space", "\t": "a tab, U+0009", "\n": "a line break, U+000A", "\r": "a carriage return, U+000D",
             "\x00": "a NUL character, U+0000"}
    if c in names:
        return names[c]
    return f"the control character U+{ord(c):04X}" if c < " " or "\x7f" <= c <= "\x9f" else f"'{c}'"


# -- reading the JSON -----------------------------------------------------------------------------


class _Refused:
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
    (its shortest form gives the number back); else :class:`_Refused` -- the store would keep
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
    return _Refused(f"the number {_quote(text, 60)} would become an xsd:double (JSON-LD reads a number with a "
                    f"fraction, an exponent or more than {INTEGER_DIGITS} digits as one), and it {why}: write "
                    'it as a string with its datatype, e.g. {"@value": "...", "@type": "xsd:decimal"}')


def _json_constant(text: str) -> _Refused:
    return _Refused(f"{text} is not a JSON number (JSON has no NaN or infinity); write it as "
                    f'{{"@value": "{"INF" if "Infinity" in text else "NaN"}", "@type": "xsd:double"}}')


def _json_object(pairs: list[tuple[str, Any]]) -> Any:
    """A JSON object; :class:`_Refused` when it gives a key twice (JSON would keep only the last)."""
    out = dict(pairs)
    if len(out) == len(pairs):
        return out
    seen: set[str] = set()
    twice = next(k for k, _ in pairs if k in seen or seen.add(k))  # type: ignore[func-returns-value]
    return _Refused(f"this object gives the key {_quote(twice)} twice; JSON keeps only one of them, so the "
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
    Values JSON-LD could not keep are :class:`_Refused` in it (see :func:`local_contexts`)."""
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
        raise JsonLdError(_too_deep(), name) from None


def _too_deep() -> str:
    return (f"arrays and objects are nested deeper than {MAX_DEPTH} levels; a program graph nests about 15 "
            "(refused so that reading it stays bounded)")


# -- the walk: contexts, keys, values -------------------------------------------------------------

#: where a value is: None (the top), or (where its container is, its key or index)
_Path = tuple[Any, str | int] | None


def pointer(path: _Path) -> str:
    """The RFC 6901 JSON pointer of ``path``."""
    tokens: list[str] = []
    while path is not None:
        path, token = path
        tokens.append(str(token).replace("~", "~0").replace("/", "~1"))
    return "".join("/" + t for t in reversed(tokens))


def _fetched(iri: str, path: _Path, name: str) -> JsonLdError:
    return JsonLdError(f"names the context {_quote(iri)} by its IRI; stepnc-graph never fetches contexts (a "
                       "document could make it connect anywhere, read local files or change what its terms "
                       f"mean): put the context in the document, or name the shipped one, {CONTEXT_IRI}",
                       name, pointer=pointer(path))


def _first_string(value: Any, path: _Path) -> tuple[str, _Path] | None:
    """The first string inside nested arrays, and where it is."""
    stack = [(value, path)]
    while stack:
        item, where = stack.pop()
        if isinstance(item, str):
            return item, where
        if isinstance(item, list):
            stack.extend((v, (where, i)) for i, v in reversed(list(enumerate(item))))
    return None


class _Contexts:
    """Resolves the contexts of one document: the shipped one is put in place (one object, not
    walked again), any other named by IRI is refused.

    The shipped context's IRI (and an ``@import`` of it) is taken in the document's top-level
    ``@context`` only: it stands for some 7,500 JSON values of term definitions, which a
    processor would process again for every node naming it -- a few bytes each, minutes of
    work for a small document. Once, at the top, is all a program needs.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self.shipped: dict[str, Any] | None = None
        #: the first scoped context that is not the shipped context's (reported after the walk,
        #: so that a context that would be fetched is reported first)
        self.unshipped: JsonLdError | None = None

    def the_shipped(self, path: _Path) -> dict[str, Any]:
        if not _at_top(path):
            raise JsonLdError(f"names the shipped context, {CONTEXT_IRI}, below the top of the document; name it "
                              "in the document's top-level @context only (it defines every term of a program, and "
                              "a processor would process all of it again here, for every node)", self.name,
                              pointer=pointer(path))
        if self.shipped is None:
            from stepnc_graph.vocabulary.jsonld_context import shipped_context

            self.shipped = shipped_context().source
        return self.shipped

    def entry(self, value: Any, path: _Path) -> Any:
        """One entry of a ``@context`` (the value itself or a member of its array)."""
        if value is None or isinstance(value, dict):
            return value
        if isinstance(value, str):
            if value != CONTEXT_IRI:
                raise _fetched(value, path, self.name)
            return self.the_shipped(path)
        if isinstance(value, list):
            inner = _first_string(value, path)
            if inner is not None and inner[0] != CONTEXT_IRI:
                raise _fetched(inner[0], inner[1], self.name)
            raise JsonLdError("an array inside a @context array: JSON-LD allows objects, null and IRIs there, "
                              "not arrays", self.name, pointer=pointer(path))
        if isinstance(value, _Refused):
            raise JsonLdError(value.message, self.name, pointer=pointer(path))
        raise JsonLdError(f"a @context is an object, null, the IRI {CONTEXT_IRI} or an array of these, not "
                          f"{json.dumps(value)}", self.name, pointer=pointer(path))

    def context(self, value: Any, path: _Path) -> Any:
        """The value of a ``@context`` key, resolved."""
        if isinstance(value, list):
            return [self.entry(v, (path, i)) for i, v in enumerate(value)]
        return self.entry(value, path)

    def imported(self, context: dict[str, Any], path: _Path) -> None:
        """Inline the shipped context where a context ``@import``\\ s it (its own terms win)."""
        value = context["@import"]
        if value != CONTEXT_IRI:
            if isinstance(value, str):
                raise _fetched(value, (path, "@import"), self.name)
            raise JsonLdError(f"@import names one context by its IRI, {CONTEXT_IRI} here, not "
                              f"{_quote(json.dumps(value))}", self.name, pointer=pointer((path, "@import")))
        del context["@import"]
        for k, v in self.the_shipped((path, "@import")).items():
            context.setdefault(k, v)

    def check_scoped(self, resolved: Any, path: _Path) -> None:
        """A node's (or the document's) context: each term definition in it that has a scoped
        context must be the shipped context's definition of that term.

        A processor processes a scoped context each time a node or value uses it, and every
        term definition with one costs it a copy of the whole active context: a document's
        own scoped contexts could make a small document cost minutes (2,000 such terms in
        one context: 0.5 s, twice as many four times that). The shipped context's are small
        and few, which bounds that work to what a program needs.
        """
        if self.unshipped is not None:
            return
        entries = resolved if isinstance(resolved, list) else [resolved]
        for i, entry in enumerate(entries):
            if not isinstance(entry, dict) or entry is self.shipped:
                continue
            from stepnc_graph.vocabulary.jsonld_context import shipped_context

            shipped = shipped_context().source
            for term, definition in entry.items():
                if isinstance(definition, dict) and "@context" in definition and definition != shipped.get(term):
                    where = ((path, i) if isinstance(resolved, list) else path, term)
                    self.unshipped = JsonLdError(
                        f"the term {_quote(term)} has a scoped context (@context) of its own; scoped contexts are "
                        "taken as the shipped context defines them (for this term: "
                        f"{'none' if term not in shipped else 'a different one'}), since a processor processes "
                        "one again for every node that uses it: define the term without @context, or as the "
                        "shipped context does", self.name, pointer=pointer(where))
                    return


def _at_top(path: _Path) -> bool:
    """Whether ``path`` is in the document's top-level ``@context`` (its value, a member of its
    array, or the ``@import`` of one of these)."""
    tokens: list[str | int] = []
    while path is not None:
        path, token = path
        tokens.append(token)
    tokens.reverse()
    if tokens[-1:] == ["@import"]:
        tokens.pop()
    return tokens[:1] == ["@context"] and (len(tokens) == 1 or (len(tokens) == 2 and isinstance(tokens[1], int)))


def _check_text(text: str, path: _Path, name: str) -> None:
    """A string holding a lone surrogate (``"\\ud800"`` in JSON) is no Unicode text: refused."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise JsonLdError("a string holds a lone surrogate (an unpaired \\ud800-\\udfff escape): no Unicode "
                          "text, so no RDF literal or IRI can hold it", name, pointer=pointer(path)) from None


def _check_key(key: str, path: _Path, name: str) -> None:
    if not key.isascii():
        _check_text(key, (path, key), name)
    if key[:1] == "@" and key not in KEYWORDS and _KEYWORD_FORM.fullmatch(key):
        raise JsonLdError(f"the key {_quote(key)} has the form of a keyword but is none; a JSON-LD processor "
                          "ignores it, so its value would be lost: give the key an IRI (or a term the context "
                          "defines)", name, pointer=pointer((path, key)))


def _check_bases(context: dict[str, Any], path: _Path, name: str) -> None:
    """A context's ``@base`` and ``@vocab`` must be IRI references: resolving against an invalid
    one could give valid-looking IRIs where JSON-LD has none."""
    for key in ("@base", "@vocab"):
        value = context.get(key)
        if isinstance(value, str) and (_NOT_IN_IRI.search(value) or _BAD_PERCENT.search(value) or (
                _SCHEME.match(value) and _iri_problem(value))):
            try:
                ox.NamedNode(value)
                error = "not one"
            except ValueError as e:
                error = str(e)
            raise JsonLdError(f"{_quote(value)} is not an IRI reference: {_iri_reason(value, error)}", name,
                              pointer=pointer((path, key)))


def _floating(value: dict[str, Any], path: _Path) -> bool:
    """Whether ``value`` is a value or list object with no node to belong to: the document itself,
    or a member of a top-level array or of a ``@graph`` array."""
    if not ("@value" in value or "@list" in value):
        return False
    if path is None:
        return True
    parent, token = path
    return isinstance(token, int) and (parent is None or parent[1] == "@graph")


def local_contexts(doc: Any, name: str) -> Any:
    """``doc``, checked all through and with every context named by an IRI resolved without the network.

    The shipped context's IRI, in the document's top-level ``@context``, becomes the
    installed context; any other IRI -- in a ``@context`` anywhere (the document, a node, a
    type- or property-scoped term definition, a nested array) or in ``@import`` -- is
    refused: a JSON-LD processor would fetch it. Refused as well, each with its JSON
    pointer: what the JSON reader marked (a key twice, a number JSON-LD cannot keep), a lone
    surrogate, a key of keyword form that is no keyword, nesting deeper than
    :data:`MAX_DEPTH`, and a scoped context (a term definition's own ``@context``) that is
    not the shipped context's (see :meth:`_Contexts.check_scoped`).
    """
    contexts = _Contexts(name)
    stack: list[tuple[Any, _Path, int, bool]] = [(doc, None, 1, False)]
    while stack:
        value, path, depth, in_context = stack.pop()
        kind = type(value)
        if kind is str:
            if not value.isascii():
                _check_text(value, path, name)
            continue
        if kind is _Refused:
            raise JsonLdError(value.message, name, pointer=pointer(path))
        if kind is not dict and kind is not list:
            continue
        if depth > MAX_DEPTH:
            raise JsonLdError(_too_deep(), name, pointer=pointer(path))
        if kind is list:
            for i, item in enumerate(value):
                if type(item) in (dict, list, _Refused) or (type(item) is str and not item.isascii()):
                    stack.append((item, (path, i), depth + 1, in_context))
            continue
        if value is contexts.shipped:  # put in place by this walk: nothing to check in it
            continue
        for key in value:
            _check_key(key, path, name)
        node_id = value.get("@id")
        if type(node_id) is str and len(node_id) > MAX_IRI:
            raise JsonLdError(f"an @id of {len(node_id):,} characters (at most {MAX_IRI:,}): every statement "
                              "about the node would repeat it", name, pointer=pointer((path, "@id")))
        if "@context" in value:
            value["@context"] = contexts.context(value["@context"], (path, "@context"))
            if not in_context:
                contexts.check_scoped(value["@context"], (path, "@context"))
        if "@import" in value:
            contexts.imported(value, path)
        if in_context:
            _check_bases(value, path, name)
        elif _floating(value, path):
            raise JsonLdError("a value on its own, in no node (JSON-LD drops it, and what it says would be "
                              "lost): give it a node and a property", name, pointer=pointer(path))
        stack.extend((item, (path, key), depth + 1, in_context or key == "@context")
                     for key, item in value.items() if item is not contexts.shipped)
    if contexts.unshipped is not None:
        raise contexts.unshipped
    return doc


# -- the processor ----------------------------------------------------------------------------------


def parse_quads(doc: Any, base: str, name: str) -> list[ox.Quad]:
    """The quads of a JSON-LD document (its contexts resolved by :func:`local_contexts`).

    Oxigraph's JSON-LD processor reads it; it cannot load a document (its binding gives it
    no loader), so a context named by IRI is an error here too. JSON-LD drops a statement
    whose IRI, blank node label or language tag is not valid; the processor is therefore
    run leniently, keeping them, and every term is checked: an invalid one is a
    :class:`JsonLdError` naming it and where it is. Lenient resolution of a reference with
    dot segments can make an invalid one valid (``"a b/../c"``); a document that has such
    segments is read a second time as JSON-LD says, and the two must agree.
    """
    data = json.dumps(doc).encode("utf-8")
    try:
        quads = list(ox.parse(data, ox.RdfFormat.JSON_LD, base_iri=base, lenient=True))
    except SyntaxError as e:
        raise _processor_error(doc, str(e.msg), name) from None
    problems, odd = _problems(quads)
    if not problems and (b"/." in data or b'".' in data):
        try:
            strict = list(ox.parse(data, ox.RdfFormat.JSON_LD, base_iri=base))
        except SyntaxError as e:
            raise _processor_error(doc, str(e.msg), name) from None
        if len(strict) != len(quads):
            problems = _masked(quads, strict)
    if problems:
        raise _dropped(doc, problems, name)
    return _relabelled(quads, odd) if odd else quads


def _problems(quads: list[ox.Quad]) -> tuple[dict[str, str], set[str]]:
    """The invalid terms of leniently read quads (up to :data:`SHOWN` and one): text -> why; and
    the blank node labels N-Triples cannot write (JSON-LD allows any text after ``_:``)."""
    valid: set[str] = set()
    problems: dict[str, str] = {}
    odd: set[str] = set()
    for q in quads:
        for term in (q.subject, q.predicate, q.object, q.graph_name):
            if isinstance(term, ox.Literal):
                key = "\x00" + term.datatype.value + "@" + (term.language or "")  # no IRI holds a NUL
            elif isinstance(term, ox.NamedNode):
                key = term.value
            elif isinstance(term, ox.BlankNode):
                if not _BLANK_LABEL.fullmatch(term.value):
                    odd.add(term.value)
                continue
            else:
                continue
            if key in valid:
                continue
            found = _invalid(term)
            if not found:
                valid.add(key)
            problems.update((text, why) for text, why in found if text not in problems)
        if len(problems) > SHOWN:
            break
    return problems, odd


def _relabelled(quads: list[ox.Quad], odd: set[str]) -> list[ox.Quad]:
    """``quads`` with each blank node whose label N-Triples cannot write given another (labels
    only tell blank nodes apart within the document: nothing is lost)."""
    labels = {label: ox.BlankNode("u" + hashlib.sha256(label.encode("utf-8", "surrogatepass")).hexdigest()[:32])
              for label in odd}

    def term(t: Any) -> Any:
        return labels.get(t.value, t) if isinstance(t, ox.BlankNode) else t

    return [ox.Quad(term(q.subject), q.predicate, term(q.object), q.graph_name) if isinstance(q.subject, ox.BlankNode)
            or isinstance(q.object, ox.BlankNode) else q for q in quads]


def _masked(lenient: list[ox.Quad], strict: list[ox.Quad]) -> dict[str, str]:
    """The IRIs lenient resolution made out of invalid references: in no statement JSON-LD keeps."""
    kept = {t for q in strict for t in (q.subject, q.predicate, q.object, q.graph_name)}
    problems: dict[str, str] = {}
    for q in lenient:
        culprit = next((t for t in (q.subject, q.object, q.predicate, q.graph_name)
                        if isinstance(t, ox.NamedNode) and t not in kept), None)
        if culprit is not None:
            problems.setdefault(culprit.value, _MASKED)
    return problems or {"(a statement)": "what JSON-LD reads: a reference in the document is no valid IRI reference"}


def _processor_error(doc: Any, message: str, name: str) -> JsonLdError:
    """The processor's complaint, without its positions (they are of the document as re-written
    here) and located in the document when it quotes a value of it."""
    message = re.sub(r"^Parser error at line \d+[^:]*: ", "", message)
    message = re.sub(r" \(line \d+\)$", "", message)
    if "LoadDocumentCallback" in message:
        return JsonLdError("names a context by its IRI; stepnc-graph never fetches contexts: put the context in "
                           f"the document, or name the shipped one, {CONTEXT_IRI}", name)
    for quoted in re.findall(r"'(.+)'", message, re.DOTALL) + re.findall(r"'(.+?)'", message, re.DOTALL):
        where = _path_of(_locate(doc, quoted))
        if where is None:
            continue
        if "must be an IRI" in message and _iri_problem(quoted):
            [(_, why)] = _iri_problem(quoted)
            return JsonLdError(f"{_quote(quoted)} is not {why}", name, pointer=pointer(where))
        return JsonLdError(f"not JSON-LD that can be read: {_printable(message)}", name, pointer=pointer(where))
    return JsonLdError(f"not JSON-LD that can be read: {_printable(message)}", name)


def _dropped(doc: Any, problems: dict[str, str], name: str) -> JsonLdError:
    """The error for a document JSON-LD would read only by dropping statements: its invalid values."""
    found = [_as_written(value, _locate(doc, value)) if why is _MASKED else (value, why, _path_of(_locate(doc, value)))
             for value, why in list(problems.items())[:SHOWN]]
    first = found[0][2] if found else None
    if len(found) == 1:
        value, why, _ = found[0]
        return JsonLdError(f"{_quote(value)} is not {why}; JSON-LD would drop it, and what it says would be lost",
                           name, pointer=pointer(first) if first is not None else None)
    shown = "; ".join(f"{_quote(value)}" + (f" at {_show_pointer(pointer(where))}" if where is not None else "")
                      + f" is not {why}" for value, why, where in found)
    return JsonLdError(f"holds {'more than ' if len(problems) > SHOWN else ''}{len(found)} values JSON-LD would "
                       f"drop, and what they say would be lost: {shown}", name,
                       pointer=pointer(first) if first is not None else None)


_MASKED = "what the document says: a reference that is no valid IRI reference was resolved to it"


def _as_written(iri: str, found: tuple[_Path, str] | None) -> tuple[str, str, _Path | None]:
    """An IRI that only lenient resolution made (``"a b/../c"`` -> ``.../c``) as the document writes it."""
    if found is None:
        return iri, _MASKED, None
    where, text = found
    return text, "a valid IRI reference: " + _iri_reason(text, "not one"), where


def _invalid(term: Any) -> list[tuple[str, str]]:
    """What is wrong with one term of a leniently read quad: (its text, why) for each invalid part."""
    out: list[tuple[str, str]] = []
    if isinstance(term, ox.NamedNode):
        out += _iri_problem(term.value)
    elif isinstance(term, ox.Literal):
        out += _iri_problem(term.datatype.value)
        if term.language is not None:
            try:
                ox.Literal(term.value, language=term.language)
            except ValueError:
                out.append((term.language, "a language tag (BCP 47, such as en or de-CH)"))
    return out


def _iri_problem(iri: str) -> list[tuple[str, str]]:
    """``[(iri, why it is not one)]``, or ``[]`` for a valid IRI."""
    try:
        ox.NamedNode(iri)
    except ValueError as e:
        return [(iri, "an IRI: " + _iri_reason(iri, str(e)))]
    return []


def _iri_reason(iri: str, error: str) -> str:
    """Why ``iri`` is not an IRI, in the terms of RFC 3987."""
    bad = _NOT_IN_IRI.search(iri)
    if bad:
        return f"it holds {_char(bad.group())}, which no IRI may hold"
    if _BAD_PERCENT.search(iri):
        return "it holds a '%' that is not followed by two hexadecimal digits"
    if not _SCHEME.match(iri):
        head = re.match(r"[^/?#]*:", iri)
        if head:
            return (f"{_quote(head.group()[:-1])} is no scheme (a scheme is a letter, then letters, digits, '+', "
                    "'-' or '.')")
        return ("it is relative, with no scheme and no base to resolve it against: a key the context does not "
                'define, or a reference where "@base" is null')
    return _printable(error)


def _ends_with(iri: str, text: str) -> bool:
    """Whether ``iri`` ends with ``text`` after a delimiter: how a relative reference or the local
    part of a compact IRI is found in what it became."""
    return bool(text) and len(iri) > len(text) and iri.endswith(text) and iri[-len(text) - 1] in "/#:?"


def _path_of(found: tuple[_Path, str] | None) -> _Path | None:
    return found[0] if found is not None else None


def _locate(doc: Any, value: str, exact: bool = False) -> tuple[_Path, str] | None:
    """Where ``value`` (an IRI as the processor made it, a blank node, a language tag) is written
    in the document: a key or string equal to it, else the longest one it ends with (a relative
    reference or a compact IRI, resolved), else a reference with dot segments ending as it does;
    outside contexts first. Its path and the text written there."""
    best: tuple[tuple[int, int, int], _Path, str] | None = None
    last = value.rsplit("/", 1)[-1]
    stack: list[tuple[Any, _Path, bool]] = [(doc, None, False)]
    while stack:
        item, path, in_context = stack.pop()
        candidates: list[tuple[str, _Path]] = []
        if isinstance(item, dict):
            for key, v in item.items():
                candidates.append((key, (path, key)))
                stack.append((v, (path, key), in_context or key == "@context"))
        elif isinstance(item, list):
            stack.extend((v, (path, i), in_context) for i, v in enumerate(item))
        elif isinstance(item, str):
            candidates.append((item, path))
        for text, where in candidates:
            if exact:
                rank = 4 if text == value else 0
            else:
                local = text.partition(":")[2]
                rank = (4 if text == value else 3 if _ends_with(value, text) else 2 if _ends_with(value, local) else
                        1 if last and text.endswith("/" + last) and ("/../" in text or "/./" in text) else 0)
            if rank:
                score = (int(not in_context), rank, len(text))
                if best is None or score > best[0]:
                    best = (score, where, text)
    return (best[1], best[2]) if best is not None else None


def named_graph_of(path: Path) -> str | None:
    """The graph a JSON-LD file names, if it is readable and names one: what it is loaded as
    without ``--base-iri``. That is the top-level ``@id`` of a graph's export, or the ``@id`` of
    the one named graph of a whole-store export; relative to ``@base``. Errors are left to the load."""
    try:
        doc = json.loads(read_bytes(path).decode("utf-8-sig"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(doc, dict):
        return None
    bases = _bases(doc)
    if not isinstance(doc.get("@id"), str):
        inner = doc.get("@graph")
        if not (isinstance(inner, list) and len(inner) == 1 and isinstance(inner[0], dict)):
            return None
        doc = inner[0]
        bases += _bases(doc)
    if not isinstance(doc.get("@id"), str) or "@graph" not in doc:
        return None
    from urllib.parse import urljoin

    try:  # urljoin raises ValueError too ("Invalid IPv6 URL" for a '[' in the authority)
        iri = urljoin(bases[-1], doc["@id"]) if bases else str(doc["@id"])
        ox.NamedNode(iri)
    except ValueError:
        return None
    return iri


def _bases(node: dict[str, Any]) -> list[str]:
    """The ``@base`` values of a node's own (inline) contexts, in order."""
    contexts = node.get("@context")
    return [c["@base"] for c in (contexts if isinstance(contexts, list) else [contexts])
            if isinstance(c, dict) and isinstance(c.get("@base"), str)]


# -- the program graph ----------------------------------------------------------------------------


def program_graph(quads: list[ox.Quad], name: str) -> tuple[str | None, list[ox.Quad]]:
    """The document's graph IRI (None when it holds only a default graph) and its quads (all of them:
    a document holds one program, one named graph or only the default graph; no copy is made)."""
    names = {q.graph_name for q in quads}
    if any(isinstance(g, ox.BlankNode) for g in names):
        raise JsonLdError("holds a graph named by a blank node; a program graph has an IRI", name)
    named = sorted(g.value for g in names if isinstance(g, ox.NamedNode))
    if len(names) > 1:
        held = ", ".join(["the default graph"] * (len(named) < len(names)) + [f"<{g}>" for g in named])
        raise JsonLdError(f"holds {len(names)} graphs ({held}); load takes one program graph per document "
                          "(export one with --graph)", name)
    if named:
        return named[0], quads
    structures = {t.subject.value for t in quads if t.predicate.value == RDF_TYPE
                  and isinstance(t.object, ox.NamedNode) and t.object.value == P21_NS + "ExchangeStructure"
                  and isinstance(t.subject, ox.NamedNode)}
    return (structures.pop() if len(structures) == 1 else None), quads


def _moved(quads: list[ox.Quad], old: str | None, new: str) -> list[ox.Quad]:
    """``quads`` with the document's graph ``old`` (and every IRI under it) moved to ``new``."""
    if old is None or old == new:
        return quads
    old_prefix, new_prefix = instance_prefix(old), instance_prefix(new)
    graph = ox.NamedNode(new)

    def move(term: Any) -> Any:
        if isinstance(term, ox.NamedNode):
            if term.value == old:
                return graph
            if term.value.startswith(old_prefix):
                return ox.NamedNode(new_prefix + term.value[len(old_prefix):])
        return term

    return [ox.Quad(move(q.subject), q.predicate, move(q.object), graph) for q in quads]


#: the classes of instances kept as their text
_RAW = frozenset({P21_NS + "RawInstance", P21_NS + "UnreadableInstance"})


@lru_cache(maxsize=1)
def _instance_classes() -> frozenset[str]:
    """Every class an instance can have: any edition's entity classes, a raw instance's and an
    unreadable one's (which is raw too; either type alone makes a numbered node an instance)."""
    return frozenset(c for e in EDITIONS for c in edition_plans(e).by_class) | _RAW


class JsonLdLoad:
    """One JSON-LD file's load into the named graph ``source.graph``.

    Everything is read and checked when it is made (so bad input never opens a
    store transaction); the loader's run then writes :meth:`chunks` atomically,
    as for a Part 21 file (:func:`stepnc_graph.loading.loader.load_source`).
    """

    def __init__(self, source: Source, raw: bytes, plans: Plans, progress: Progress | None = None) -> None:
        self.started = time.perf_counter()
        self.source = source
        self.raw = raw
        self.plans = plans
        self.progress = progress
        self.graph = source.graph
        self.result = LoadResult(source.name, source.graph)
        #: none of the derived layer is written with the chunks: derive() finds it all in the store
        self.derived_written: int | None = None
        self.derived = True  # whether the load writes a derived layer (see loader.load_source)
        doc = local_contexts(parse_json(raw, source.name), source.name)
        old, quads = program_graph(parse_quads(doc, instance_prefix(source.graph), source.name), source.name)
        self.lines = self._lines(_moved(quads, old, self.graph), doc)
        self.result.triples = len(self.lines)

    @classmethod
    def of_source(cls, source: Source, progress: Progress | None = None) -> "JsonLdLoad":
        """The load of the ``.jsonld`` file ``source``, read and checked: :class:`JsonLdError` (bad
        input: exit 2) when it is not JSON, names a context that would have to be fetched, holds
        several graphs or no instance, or cannot be written back as Part 21."""
        if source.path is None:
            raise JsonLdError("JSON-LD is read from a .jsonld file, not standard input", source.name)
        return cls(source, read_bytes(source.path), iso14649_plans(), progress)

    # what the loader's run asks of a load (stepnc_graph.loading.loader._run)

    def dangling(self, store: Store, where: str) -> list[Diagnostic]:
        """References to unreadable instances: a JSON-LD document has none."""
        return []

    def diagnostics(self) -> list[Diagnostic]:
        return []

    def instances(self, quads: list[ox.Quad]) -> dict[Any, list[str]]:
        """Instance nodes (a class of any edition's schema, or kept raw) and their types.

        A graph read in another edition (``p21:edition``) holds classes the shipped schema does not
        have; they are instances too, or the count would not match the graph's numbered instances."""
        types: dict[Any, list[str]] = defaultdict(list)
        known = _instance_classes()
        for t in quads:
            if t.predicate.value == RDF_TYPE and isinstance(t.object, ox.NamedNode) and t.object.value in known:
                types[t.subject].append(t.object.value)
        return types

    def _plans_of(self, quads: list[ox.Quad]) -> dict[Any, Plans]:
        """The plans each node was read with: its own ``p21:edition``, else its graph's, else the
        shipped edition's (:attr:`plans`)."""
        editions = {t.subject: t.object.value for t in quads
                    if t.predicate.value == P21_NS + "edition" and isinstance(t.object, ox.Literal)}
        default = editions.get(ox.NamedNode(self.graph))

        def plans(edition: str | None) -> Plans:
            return edition_plans(edition) if edition in EDITIONS else self.plans

        shared = plans(default)
        return defaultdict(lambda: shared, {node: plans(e) for node, e in editions.items()})

    def program(self, quads: list[ox.Quad]) -> list[ox.Quad]:
        """The statements kept from the document: all but its load metadata and aliases."""
        g, aliases, activity = self.graph, instance_prefix(self.graph) + "id/", instance_prefix(self.graph) + "load"

        def kept(t: ox.Quad) -> bool:
            s = t.subject.value if isinstance(t.subject, ox.NamedNode) else ""
            if s == g:
                return t.predicate.value not in LOAD_PREDICATES
            return s != activity and not s.startswith(TOOL_IRI) and not (
                s.startswith(aliases) and t.predicate.value == OWL_SAME_AS)

        return [t for t in quads if kept(t)]

    def aliases(self, types: dict[Any, list[str]], program: list[ox.Quad]) -> list[str]:
        """``owl:sameAs`` aliases for unshared its_ids, as a Part 21 load mints them."""
        values: dict[tuple[Any, str], list[Any]] = defaultdict(list)
        for t in program:
            values[(t.subject, t.predicate.value)].append(t.object)
        labels: dict[tuple[str, str], Any] = {}
        plans_of = self._plans_of(program)
        for node, classes in types.items():
            by_class = plans_of[node].by_class
            plans = [by_class[c] for c in classes if c in by_class]
            slots = ([p.slots[p.its_id] for p in plans if p.its_id is not None] if len(plans) == 1
                     else [p.own_slots[p.own_its_id] for p in plans if p.own_its_id is not None])
            for slot in slots:
                for value in values.get((node, slot.prop), []):
                    if isinstance(value, ox.Literal) and value.datatype.value == XSD + "string" and value.value:
                        key = (slot.entity, value.value)
                        labels[key] = None if key in labels else node
        return [f"<{alias_iri(self.graph, scope, label)}> <{OWL_SAME_AS}> {node} .\n"
                for (scope, label), node in sorted(labels.items()) if node is not None]

    def metadata(self, types: dict[Any, list[str]], derived_from: list[Any]) -> list[str]:
        """This load's metadata and provenance (as a Part 21 load writes them)."""
        s, path = f"<{self.graph}>", self.source.path
        now = f'"{load_time().isoformat(timespec="seconds")}"^^<{XSD}dateTime>'
        activity, tool = f"<{instance_prefix(self.graph)}load>", f"<{TOOL_IRI}{__version__}>"
        raw_count = sum(not _RAW.isdisjoint(classes) for classes in types.values())
        where = str(path.resolve()) if path is not None else self.source.name
        out = [f"{s} <{RDF_TYPE}> <{P21_NS}ExchangeStructure> .\n", f"{s} <{RDF_TYPE}> <{PROV}Entity> .\n",
               f"{s} <{DCT}source> {ox.Literal(where)} .\n",
               f"{s} <{P21_NS}byteSize> {_integer(len(self.raw))} .\n",
               f"{s} <{P21_NS}sha256> {ox.Literal(hashlib.sha256(self.raw).hexdigest())} .\n",
               f"{s} <{P21_NS}instanceCount> {_integer(len(types))} .\n",
               f"{s} <{P21_NS}rawInstanceCount> {_integer(raw_count)} .\n",
               f"{s} <{PROV}generatedAtTime> {now} .\n", f"{s} <{PROV}wasGeneratedBy> {activity} .\n",
               f"{activity} <{RDF_TYPE}> <{PROV}Activity> .\n", f"{activity} <{PROV}wasAssociatedWith> {tool} .\n",
               f"{activity} <{PROV}endedAtTime> {now} .\n", f"{tool} <{RDF_TYPE}> <{PROV}SoftwareAgent> .\n",
               f"{tool} <{RDFS}label> {ox.Literal('stepnc-graph ' + __version__)} .\n"]
        if path is not None:
            uri = ox.NamedNode(path.resolve().as_uri())
            out += [f"{s} <{PROV}hadPrimarySource> {uri} .\n", f"{activity} <{PROV}used> {uri} .\n"]
        out += [f"{s} <{PROV}wasDerivedFrom> {source} .\n" for source in derived_from]
        return out

    def _lines(self, quads: list[ox.Quad], doc: Any) -> list[str]:
        """Every triple of the graph to write, as N-Triples lines (duplicates removed); the loader
        adds ``p21:diagnosticCount`` when it commits."""
        types = self.instances(quads)
        if not types:
            raise JsonLdError("holds no STEP-NC instance (no node of a class of the ISO 14649 vocabulary); "
                              "is it a program graph exported by stepnc-graph?", self.source.name)
        program = self.program(quads)
        graph = ox.NamedNode(self.graph)
        earlier = [t.object for t in quads if t.subject == graph
                   and t.predicate.value == PROV + "hadPrimarySource" and isinstance(t.object, ox.NamedNode)]
        self._check_writable(program, doc)
        lines = [f"{t.subject} {t.predicate} {t.object} .\n" for t in program]
        lines += self.aliases(types, program) + self.metadata(types, earlier)
        self.result.instances = self.result.defined = len(types)
        self.result.raw = sum(not _RAW.isdisjoint(classes) for classes in types.values())
        return list(dict.fromkeys(lines))

    def _check_writable(self, program: list[ox.Quad], doc: Any) -> None:
        """Refuse a graph the Part 21 writer cannot write (a value that fits no parameter, a broken
        list, an instance number that is no number)."""
        from stepnc_graph.mapping.writer import WriteError, write_graph

        name = self.source.name
        for q in program:
            what = _NUMBERED.get(q.predicate.value)
            if what is not None and not (isinstance(q.object, ox.Literal) and _WHOLE.fullmatch(q.object.value)):
                value = q.object.value if isinstance(q.object, (ox.Literal, ox.NamedNode, ox.BlankNode)) else ""
                raise JsonLdError(f"cannot be written back as Part 21: {q.subject} has {what[0]} {_quote(value)}, "
                                  f"which is no {what[1]} (a whole number)", name,
                                  pointer=pointer(where) if (where := _path_of(_locate(doc, value, exact=True))) else None)
        try:
            write_graph(self.plans, program, self.graph)
        except WriteError as e:
            raise JsonLdError(f"cannot be written back as Part 21: {e}", name) from None
        except (ValueError, KeyError, IndexError):  # a value the writer does not expect where it is
            raise JsonLdError("cannot be written back as Part 21: the Part 21 writer met a value it cannot place "
                              "(a p21: bookkeeping value edited by hand?); compare the document with an export",
                              name) from None

    def chunks(self) -> Iterator[str]:
        """N-Triples chunks of about CHUNK_TRIPLES lines; the triples of connected blank nodes stay in
        one chunk (a bulk load names blank nodes per call)."""
        parent: dict[str, str] = {}

        def find(x: str) -> str:
            while parent.setdefault(x, x) != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        keys = []
        lines = self.lines
        for line in lines:  # a blank node is the subject or the last term: blanks hold no spaces
            terms = [t for t in (line[:line.index(" ")], line[line.rindex(" ", 0, len(line) - 3) + 1:-3])
                     if t.startswith("_:")]
            if len(terms) == 2:
                parent[find(terms[0])] = find(terms[1])
            keys.append(terms[0] if terms else "")
        groups: dict[str, list[str]] = defaultdict(list)
        for line, key in zip(lines, keys, strict=True):
            groups[find(key) if key else ""].append(line)
        out: list[str] = []
        for group in groups.values():
            out.extend(group)
            if len(out) >= CHUNK_TRIPLES:
                yield "".join(out)
                out.clear()
        if out:
            yield "".join(out)
        if self.progress is not None:
            self.progress(len(self.raw), len(self.raw))


def _integer(value: int) -> str:
    return f'"{value}"^^<{XSD}integer>'
