"""Query results: the SPARQL 1.1 results formats and the tables people read, safe in a spreadsheet
and on a terminal; the prefixes queries may use undeclared; the error a query that cannot run raises.

Split from :mod:`stepnc_graph.querying.query` (which runs queries and re-exports these names): a
result is written the same way whichever query, library or store gave it. ``csv``, ``tsv`` and
``json`` are written by Oxigraph's own serialisers -- except that in CSV and TSV a text a spreadsheet
would run as a formula (``=1+2``, ``@SUM(A1)``) gets a leading ``'`` unless ``csv_raw`` asks for the
W3C form exactly (:func:`formula_guard`).
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.core.formats import QUERY_RESULT_FORMATS
from stepnc_graph.core.naming import ANALYSIS_NS, ATTRIBUTE_NS, DATA_BASE, P21_NS, STEPNC_NS

XSD = "http://www.w3.org/2001/XMLSchema#"
#: Prefixes every query may use without declaring them (library queries declare theirs anyway).
PREFIXES: dict[str, str] = {
    "stepnc": STEPNC_NS,
    "attr": ATTRIBUTE_NS,
    "sga": ANALYSIS_NS,
    "p21": P21_NS,
    "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#",
    "rdfs": "http://www.w3.org/2000/01/rdf-schema#",
    "owl": "http://www.w3.org/2002/07/owl#",
    "xsd": XSD,
    "skos": "http://www.w3.org/2004/02/skos/core#",
    "dcterms": "http://purl.org/dc/terms/",
    "prov": "http://www.w3.org/ns/prov#",
}
#: Prefixes used to shorten IRIs in the ``table`` and ``md`` formats only.
DISPLAY_PREFIXES = {**PREFIXES, "data": DATA_BASE}
FORMATS = QUERY_RESULT_FORMATS
#: The formats of CONSTRUCT and DESCRIBE results (RDF): the others give N-Triples for them.
RDF_FORMATS = ("ttl", "nt")


class QueryError(StepncGraphError, ValueError):
    """A query that cannot run as asked: syntax error, bad parameter, unknown name or graph.

    ``source`` is the query file (or ``-e``), ``line``/``column`` 1-based
    positions in it when known, ``parameter`` the parameter at fault.
    """

    def __init__(self, message: str, source: str = "", line: int | None = None, column: int | None = None,
                 parameter: str | None = None, excerpt: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.source = source
        self.line = line
        self.column = column
        self.parameter = parameter
        self.excerpt = excerpt

    def __str__(self) -> str:
        where = self.source
        if self.line is not None:
            where += f":{self.line}" + (f":{self.column}" if self.column is not None else "")
        text = f"{where}: {self.message}" if where else self.message
        if self.excerpt is not None and self.column is not None:
            text += f"\n  {self.excerpt}\n  {' ' * (self.column - 1)}^"
        return text

    def asdict(self) -> dict[str, Any]:
        return {"source": self.source, "line": self.line, "column": self.column, "parameter": self.parameter,
                "message": self.message}


Term = ox.NamedNode | ox.BlankNode | ox.Literal | ox.Triple

#: A spreadsheet opening CSV or TSV reads a cell starting with one of these as a formula (the
#: characters OWASP's "CSV Injection" guidance names: =, +, -, @, tab, carriage return).
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")
#: The numeric datatypes whose values CSV and TSV write bare: a negative number is not a formula.
_NUMERIC = frozenset(XSD + t for t in (
    "integer", "decimal", "double", "float", "long", "int", "short", "byte", "nonNegativeInteger",
    "nonPositiveInteger", "negativeInteger", "positiveInteger", "unsignedLong", "unsignedInt", "unsignedShort",
    "unsignedByte"))
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
#: A JSON string starting with one of :data:`FORMULA_STARTS` (tab and CR are escaped in JSON), in any
#: layout: results without one are written by Oxigraph straight from its JSON, as before.
_MAYBE_FORMULA = re.compile(rb'"(?:[=+@-]|\\[tr]|\\u000[9dD])')
#: Such a literal as Oxigraph's JSON writer lays it out (value, then its datatype if any).
_LITERAL_AT_RISK = re.compile(rb'"type":"literal","value":"(?P<value>(?:[=+@-]|\\[tr]|\\u000[9dD])(?:[^"\\]|\\.)*)"'
                              rb'(?:,"datatype":"(?P<datatype>[^"\\]*)")?')


def formula_guard(value: str, datatype: str | None = None) -> str:
    """A literal's text for a CSV or TSV cell: with a ``'`` before it if a spreadsheet would run it.

    OWASP's advice for CSV injection: a text starting with ``=``, ``+``, ``-``, ``@``, tab or CR
    gets a leading apostrophe, which spreadsheets show as text. A number of a numeric datatype
    (``-3.5``, ``-1.5E3``) keeps its sign: it is a number there too. Any other text does, a string
    ``"-3.5"`` or a ``"-INF"`` included.
    """
    if not value.startswith(FORMULA_STARTS) or (datatype in _NUMERIC and _NUMBER.fullmatch(value)):
        return value
    return "'" + value


def _guard_formulas(data: bytes) -> bytes:
    """SPARQL JSON results with every literal :func:`formula_guard` changes changed in place.

    Only the literals that start like a formula are decoded: on 20,000 rows that all start so, 5-37 ms
    CPU, where parsing the whole result and writing it again as JSON costs 85-97 ms, against 36-40 ms
    for Oxigraph's CSV writing itself. If none is found in Oxigraph's layout although a value starts
    so (an escaped quote before it, or another layout), the whole result is rewritten.
    """
    found = False

    def guard(match: re.Match[bytes]) -> bytes:
        nonlocal found
        found = True
        text = match["value"]
        value = json.loads(b'"' + text + b'"') if b"\\" in text else text.decode()
        datatype = match["datatype"].decode() if match["datatype"] is not None else None
        if formula_guard(value, datatype) == value:
            return match[0]
        return match[0].replace(b'"value":"', b'"value":"\'', 1)

    guarded = _LITERAL_AT_RISK.sub(guard, data)
    return guarded if found else _rewrite_values(data, True, None)


def _rewrite_values(data: bytes, guard: bool, cell: Callable[[str], str] | None) -> bytes:
    """SPARQL JSON results with each literal's text through :func:`formula_guard` (``guard``) and
    then ``cell``; IRIs and blank nodes, which never start like a formula, are left as they are."""
    doc = json.loads(data)

    def rewrite(term: dict[str, Any]) -> None:
        if term["type"] == "triple":
            for part in term["value"].values():
                rewrite(part)
        elif term["type"] == "literal":
            value = formula_guard(term["value"], term.get("datatype")) if guard else term["value"]
            term["value"] = cell(value) if cell is not None else value

    for binding in doc.get("results", {}).get("bindings", []):
        for term in binding.values():
            rewrite(term)
    return json.dumps(doc, ensure_ascii=False).encode("utf-8")


def python_value(term: Term | None) -> Any:
    """A term as a plain Python value: numbers and booleans typed, IRIs and strings as text."""
    if term is None:
        return None
    if isinstance(term, ox.Literal):
        dt = term.datatype.value.removeprefix(XSD)
        if dt in ("integer", "int", "long", "short", "nonNegativeInteger", "positiveInteger"):
            return int(term.value)
        if dt in ("double", "float", "decimal"):
            return float(term.value)
        if dt == "boolean":
            return term.value in ("true", "1")
        return term.value
    if isinstance(term, ox.BlankNode):
        return f"_:{term.value}"
    return str(term.value) if isinstance(term, ox.NamedNode) else str(term)


def display(term: Term | None) -> str:
    """A term for reading: prefixed IRIs, literal values without their datatype."""
    if term is None:
        return ""
    if isinstance(term, ox.NamedNode):
        for prefix, ns in DISPLAY_PREFIXES.items():
            if term.value.startswith(ns) and len(term.value) > len(ns):
                return f"{prefix}:{term.value[len(ns):]}"
        return f"<{term.value}>"
    if isinstance(term, ox.Literal):
        return term.value
    return str(term)


@dataclass
class QueryResult:
    """What a query returned: SELECT rows, an ASK boolean or CONSTRUCT/DESCRIBE triples.

    Iterating gives one dict per row (plain Python values, see
    :func:`python_value`); :meth:`to_dataframe` gives a pandas DataFrame;
    :meth:`serialize` gives the standard results formats.
    """

    kind: str  # "select", "ask" or "graph"
    variables: list[str] = field(default_factory=list)
    #: the rows as terms; None until :attr:`terms` first reads them from the JSON results
    _terms: list[tuple[Term | None, ...]] | None = field(default=None, repr=False)
    boolean: bool | None = None
    triples: list[ox.Triple] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    _json: bytes = b""

    @property
    def terms(self) -> list[tuple[Term | None, ...]]:
        """The SELECT rows as terms, in the order of :attr:`variables`.

        Parsed from the JSON results on first use: writing ``json``, ``csv`` or ``tsv`` (what
        ``stepnc-graph query --format json`` does) needs no Python term per value, which for a
        thousand-row result is a fifth of the query's time.
        """
        if self._terms is None:
            self._terms = []
            if self.kind == "select" and self._json:
                parsed = ox.parse_query_results(self._json, format=ox.QueryResultsFormat.JSON)
                assert isinstance(parsed, ox.QuerySolutions)
                self._terms = [tuple(row[v] for v in self.variables) for row in parsed]
        return self._terms

    def __iter__(self) -> Iterator[dict[str, Any]]:
        for row in self.terms:
            yield {v: python_value(t) for v, t in zip(self.variables, row, strict=True)}

    def __len__(self) -> int:
        return len(self.terms) if self.kind == "select" else len(self.triples)

    @property
    def rows(self) -> list[dict[str, Any]]:
        return list(self)

    def column(self, name: str) -> list[Any]:
        i = self.variables.index(name)
        return [python_value(row[i]) for row in self.terms]

    def to_dataframe(self) -> Any:
        """The rows as a pandas DataFrame (needs pandas; ``pip install pandas``)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("to_dataframe() needs pandas: pip install pandas") from None
        return pd.DataFrame(self.rows, columns=self.variables)

    def _repr_html_(self) -> str:  # Jupyter
        from html import escape

        if self.kind != "select":
            return f"<pre>{escape(self.serialize('table').decode())}</pre>"
        head = "".join(f"<th>{escape(v)}</th>" for v in self.variables)
        body = "".join("<tr>" + "".join(f"<td>{escape(display(t))}</td>" for t in row) + "</tr>"
                       for row in self.terms)
        return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"

    def display_rows(self) -> list[list[str]]:
        return [[display(t) for t in row] for row in self.terms]

    def serialize(self, fmt: str, *, csv_raw: bool = False, cell: Callable[[str], str] | None = None,
                  width: int | None = None) -> bytes:
        """``csv``/``tsv``/``json``: the SPARQL 1.1 results formats (Oxigraph's writers); ``md``: a
        Markdown table; ``table``: aligned text, fitted to ``width`` columns when given (long cells
        cut with an ellipsis). CONSTRUCT and DESCRIBE results are RDF: ``ttl`` (Turtle with the
        query prefixes) or ``nt``, and N-Triples in the other formats; ``ttl``/``nt`` are for them only.

        In ``csv`` and ``tsv`` a literal a spreadsheet would run as a formula gets a leading ``'``
        (:func:`formula_guard`); ``csv_raw`` writes the W3C form exactly. ``cell`` is applied to
        each value's text before ``table``, ``md``, ``csv`` and ``tsv`` lay it out (the CLI passes
        its terminal escaping when it writes to a terminal, so columns and rows stay aligned).
        """
        if fmt not in FORMATS:
            raise QueryError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
        if self.kind == "graph":
            if fmt == "ttl":
                return ox.serialize(self.triples, format=ox.RdfFormat.TURTLE, prefixes=PREFIXES) or b""
            return ox.serialize(self.triples, format=ox.RdfFormat.N_TRIPLES) or b""
        if fmt in RDF_FORMATS:
            raise QueryError(f"{fmt} is for CONSTRUCT and DESCRIBE results (RDF); a {self.kind.upper()} result is "
                             "written as table, csv, tsv, json or md")
        if fmt == "json":
            return self._json if self._json.endswith(b"\n") else self._json + b"\n"
        if fmt in ("csv", "tsv"):
            return self._sparql_table(fmt, csv_raw, cell)
        if self.kind == "ask":
            return f"{str(self.boolean).lower()}\n".encode()
        rows = self.display_rows()
        if cell is not None:
            rows = [[cell(c) for c in row] for row in rows]
        if fmt == "md":
            def markdown(text: str) -> str:
                return text.replace("|", "\\|").replace("\n", " ")
            lines = ["| " + " | ".join(self.variables) + " |", "|" + "---|" * len(self.variables)]
            lines += ["| " + " | ".join(markdown(c) for c in row) + " |" for row in rows]
            return ("\n".join(lines) + "\n").encode()
        widths = _fit([max([len(v)] + [len(r[i]) for r in rows]) for i, v in enumerate(self.variables)], width)
        lines = ["  ".join(_cut(v, w).ljust(w) for v, w in zip(self.variables, widths, strict=True)).rstrip()]
        lines += ["  ".join(_cut(c, w).ljust(w) for c, w in zip(row, widths, strict=True)).rstrip() for row in rows]
        return ("\n".join(lines) + "\n").encode()

    def _sparql_table(self, fmt: str, csv_raw: bool, cell: Callable[[str], str] | None) -> bytes:
        """SPARQL 1.1 CSV or TSV by Oxigraph's writer, from the JSON results with literals guarded
        (unless ``csv_raw``) and passed through ``cell``; an ASK result is Oxigraph's ``true``/``false``."""
        data = self._json
        guard = self.kind == "select" and not csv_raw and _MAYBE_FORMULA.search(data) is not None
        if cell is not None and self.kind == "select":
            data = _rewrite_values(data, guard, cell)
        elif guard:
            data = _guard_formulas(data)
        target = ox.QueryResultsFormat.CSV if fmt == "csv" else ox.QueryResultsFormat.TSV
        parsed = ox.parse_query_results(data, format=ox.QueryResultsFormat.JSON)
        return parsed.serialize(format=target) or b""


def _fit(widths: list[int], width: int | None, least: int = 6) -> list[int]:
    """Column widths that fit ``width`` characters with two spaces between columns: the widest
    column gives way first, none below ``least`` (a table too wide even so stays too wide)."""
    widths = list(widths)
    if width is None:
        return widths
    excess = sum(widths) + 2 * (len(widths) - 1) - width
    while excess > 0:
        k = max(range(len(widths)), key=lambda i: widths[i])
        if widths[k] <= least:
            break
        widths[k] -= 1
        excess -= 1
    return widths


def _cut(text: str, width: int) -> str:
    """``text`` in ``width`` characters: one line, cut with an ellipsis when longer."""
    text = text.replace("\n", " ")
    return text if len(text) <= width else text[:max(width - 1, 0)] + "\u2026"
