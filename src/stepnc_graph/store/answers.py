"""What a SPARQL endpoint answered, read as the embedded store's answers, checked and leniently.

A query's answer must be what the query asks for (SPARQL results with its variables, a boolean,
RDF) and a complete document; where the SPARQL results formats are lenient, or a known store
answers otherwise, the answer is read as it means (:func:`lenient_json_results`). A store's own
system graphs are told apart from the user's (:func:`system_graph`).
"""

from __future__ import annotations

import re
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.outbound import outbound_keyword
from stepnc_graph.store import StoreError

_RESULTS_JSON = "application/sparql-results+json"
_NTRIPLES = "application/n-triples"


class RemoteError(StoreError):
    """A request the remote store refused or could not answer (after the retries)."""


#: the graphs stores keep for themselves in every database (their IRIs start so): Virtuoso's
#: RDF views, its Linked Data Platform vocabulary and its service description; GraphDB's
#: inferred and system graphs. They are not the user's data, so no command lists, exports or
#: queries them as such.
SYSTEM_GRAPHS = ("http://www.openlinksw.com/schemas/virtrdf#", "http://www.w3.org/ns/ldp#",
                 "http://localuriqaserver/", "http://www.ontotext.com/")


def system_graph(name: str) -> bool:
    """Whether ``name`` is one of a store's own graphs (:data:`SYSTEM_GRAPHS`)."""
    return name.startswith(SYSTEM_GRAPHS)


#: what a query's answer must be: "boolean", "graph", or the SELECT's variables
Expected = str | tuple[str, ...]


def _expected(sparql: str, prefixes: dict[str, str] | None, substitutions: dict[Any, Any] | None) -> Expected | None:
    """What answer ``sparql`` asks for, as Oxigraph parses it (on an empty store, where nothing is
    found); None for a query with a SERVICE clause (which must not run here). Raises the
    SyntaxError or RuntimeError the embedded store raises."""
    if outbound_keyword(sparql) is not None:
        return None
    result = ox.Store().query(sparql, prefixes=prefixes, substitutions=substitutions)
    if isinstance(result, ox.QueryBoolean):
        return "boolean"
    if isinstance(result, ox.QueryTriples):
        return "graph"
    return tuple(v.value for v in result.variables)


def _kind(media_type: str) -> str:
    """A media type as words for a message."""
    if media_type in ("text/html", "application/xhtml+xml"):
        return "an HTML page (a login page or a proxy's error page?)"
    return media_type or "a body without a Content-Type"


def _answer(endpoint: str, content_type: str, content: bytes, expected: Expected | None) -> Any:
    """A query's answer (pyoxigraph results, or a list of triples), checked against what the
    query asks for; RemoteError naming ``endpoint`` and what was expected otherwise."""
    media_type = content_type.split(";")[0].strip().lower()
    wanted = ("RDF (N-Triples)" if expected == "graph" else "a boolean" if expected == "boolean" else
              f"SPARQL results with {' '.join('?' + v for v in expected)}" if expected is not None else "SPARQL results")
    rdf = ox.RdfFormat.from_media_type(media_type)
    results = {_RESULTS_JSON: ox.QueryResultsFormat.JSON,
               "application/sparql-results+xml": ox.QueryResultsFormat.XML}.get(media_type)
    if (expected == "graph" and rdf is None) or (expected != "graph" and results is None and rdf is None):
        raise RemoteError(f"{endpoint} answered {_kind(media_type)} where {wanted} were expected")
    try:
        if rdf is not None:
            if expected not in (None, "graph"):
                raise RemoteError(f"{endpoint} answered RDF ({media_type}) where {wanted} were expected")
            return list(ox.parse(content, rdf))
        assert results is not None
        if results == ox.QueryResultsFormat.JSON:
            content = lenient_json_results(content, expected == "boolean")
        parsed = ox.parse_query_results(content, results)
        if isinstance(parsed, ox.QuerySolutions):
            got: Expected = tuple(v.value for v in parsed.variables)
            parsed.serialize(format=ox.QueryResultsFormat.TSV)  # reads every row: a cut document fails here
        else:
            got = "boolean"
    except SyntaxError as exc:
        raise RemoteError(f"{endpoint} answered {media_type} that does not parse (cut short?): {exc}") from None
    if expected is not None and (got == "boolean") != (expected == "boolean"):
        raise RemoteError(f"{endpoint} answered {'a boolean' if got == 'boolean' else 'rows'} where {wanted} "
                          f"were expected")
    if expected is not None and got != "boolean" and set(got) != set(expected):
        raise RemoteError(f"{endpoint} answered with the variables {' '.join('?' + v for v in got) or '(none)'} "
                          f"where {wanted} were expected")
    return ox.parse_query_results(content, results)


_XSD_DOUBLE = "http://www.w3.org/2001/XMLSchema#double"
#: the lexical form of each xsd:double literal in N-Triples (the loader writes them unescaped)
_DOUBLE = re.compile(rb'"([^"\\]*)"\^\^<' + re.escape(_XSD_DOUBLE.encode()) + rb">")


def _number(text: str) -> str:
    """An xsd:double's value, for comparing two lexical forms (NaN equal to itself)."""
    try:
        return repr(float(text.replace("INF", "inf")))
    except ValueError:
        return text


#: a blank node label the SPARQL results formats allow but Oxigraph's parser does not (Virtuoso
#: writes ``nodeID://b10576``): anything but the characters of a Turtle blank node label
_LABEL_UNSAFE = re.compile(r"[^A-Za-z0-9_]")
#: the variable of the one-row table Virtuoso 7 answers an ASK query with, in place of a boolean
_VIRTUOSO_ASK = "__ASK_RETVAL"


def store_label(node: Any) -> str | None:
    """The label a store wrote for a blank node read from its answers, where
    :func:`lenient_json_results` rewrote it (``x`` and its UTF-8 bytes in hex); None otherwise."""
    value = getattr(node, "value", "")
    if not isinstance(node, ox.BlankNode) or not value.startswith("x"):
        return None
    try:
        return bytes.fromhex(value[1:]).decode("utf-8")
    except ValueError:
        return None


def lenient_json_results(content: bytes, boolean: bool) -> bytes:
    """SPARQL JSON results as Oxigraph's strict parser takes them, where the results format is
    lenient or a known store answers otherwise (the document is rewritten only then).

    * A blank node's label is any string in the JSON results format (it only identifies the node
      within the document); Oxigraph accepts only Turtle's label characters. A label with other
      characters is written as ``x`` and its UTF-8 bytes in hex: the same label always the same.
    * Virtuoso 7 answers an ASK query with a one-column table ``__ASK_RETVAL`` (one row holding
      1 for true, no row for false): read as the boolean it means, when a boolean is expected.
    """
    if b'"bnode"' not in content and not (boolean and _VIRTUOSO_ASK.encode() in content):
        return content
    import json

    try:
        document = json.loads(content)
    except ValueError:
        return content  # the strict parser says what is wrong
    if not isinstance(document, dict):
        return content
    head: Any = document.get("head") if isinstance(document.get("head"), dict) else {}
    results: Any = document.get("results")
    rows = results.get("bindings") if isinstance(results, dict) else None
    if boolean and head.get("vars") == [_VIRTUOSO_ASK] and isinstance(rows, list) and len(rows) <= 1:
        value = rows[0].get(_VIRTUOSO_ASK, {}).get("value") if rows and isinstance(rows[0], dict) else None
        return json.dumps({"head": {}, "boolean": value not in (None, "0", "false")}).encode()

    def safe(term: Any) -> Any:
        if isinstance(term, dict) and term.get("type") == "bnode" and isinstance(term.get("value"), str):
            label = term["value"]
            if _LABEL_UNSAFE.search(label) or not label:
                # the same label the same way in every answer: a store that keeps its labels
                # from one query to the next (Virtuoso does) still lets one answer's node be
                # found in the next, as the derivation of a program's lists needs
                term = {**term, "value": "x" + label.encode("utf-8").hex()}
        return term

    for row in rows if isinstance(rows, list) else ():
        if isinstance(row, dict):
            for name, term in row.items():
                row[name] = safe(term)
    return json.dumps(document).encode()
