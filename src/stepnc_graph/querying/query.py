"""SPARQL over the store: the query library, parameters bound as RDF terms, results in standard formats.

A library query is a ``queries/<name>.rq`` file (shipped in the wheel) that
starts with a header of ``#`` comment lines::

    # title: Workingsteps by tool type
    # description: Workingsteps whose tool body is of a class (subclasses count),
    #   with operation, feature, tool and setup.
    # param: tool_type (class) = grooving_tool -- the tool body class
    # example: stepnc-graph query workingsteps-by-tool-type --param tool_type=knurling_tool

A parameter is a variable the query SELECTs (Oxigraph substitutes values only
for projected variables, SPARQL 1.1 SEP-0007 style). Its value is converted to
an RDF term of the declared type -- ``class`` (a vocabulary class, checked
against the store's vocabulary graph), ``iri``, ``string``, ``integer``,
``decimal``, ``boolean`` -- and handed to Oxigraph as a term: user text is
never spliced into the query string.

Queries run over every loaded program: the default graph is the union of all
graphs (files, their derived layers, the vocabulary), and ``GRAPH ?program``
reaches the files' own graphs (``?program`` names the source). ``graph=``
restricts both to one file. Queries are SPARQL *queries* (pyoxigraph's
``Store.query`` cannot run an update), so they are read-only by construction.

Results: :class:`QueryResult`; ``csv``, ``tsv`` and ``json`` are the SPARQL
1.1 results formats, written by Oxigraph's own serialisers -- except that in CSV
and TSV a text a spreadsheet would run as a formula (``=1+2``, ``@SUM(A1)``) gets
a leading ``'`` unless ``csv_raw`` asks for the W3C form exactly (:func:`formula_guard`).
"""

from __future__ import annotations

import dataclasses
import difflib
import json
import re
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.core.formats import QUERY_RESULT_FORMATS
from stepnc_graph.core.naming import (
    ANALYSIS_NS,
    ATTRIBUTE_NS,
    DATA_BASE,
    P21_NS,
    STEPNC_NS,
    VOCABULARY_GRAPH,
    derived_graph_iri,
    listed_graphs,
    program_graphs,
)
from stepnc_graph.core.errors import option
from stepnc_graph.core.outbound import OutboundRefused, refuse_outbound
from stepnc_graph.core.resources import queries_dir
from stepnc_graph.graphs.vocabulary_graph import is_throwaway, vocabulary_for_queries, vocabulary_status

from stepnc_graph.querying.sparql_errors import explain
from stepnc_graph.querying.terms import term_warnings
from stepnc_graph.store.behaviour import wrong_answers


if TYPE_CHECKING:
    from stepnc_graph.store.contract import Store

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
PARAM_TYPES = ("class", "iri", "string", "integer", "decimal", "boolean")
NAME = re.compile(r"^[a-z0-9][a-z0-9-]*$")
_PARAM = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*\((?P<type>[a-z]+)\)\s*"
                    r"(?:=\s*(?P<default>.*?))?\s*(?:--\s*(?P<doc>.*))?$")
_POSITION = re.compile(r"error at (\d+):(\d+): (.*)", re.S)


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


@dataclass(frozen=True)
class Param:
    """A declared parameter: ``?name`` bound to a term of ``type`` (default used when not given)."""

    name: str
    type: str
    default: str | None
    doc: str
    line: int  # where the header declares it

    def describe(self) -> str:
        default = f" = {self.default}" if self.default is not None else " (required)"
        return f"{self.name} ({self.type}){default}" + (f" -- {self.doc}" if self.doc else "")


@dataclass(frozen=True)
class Query:
    """A query with its header: a library query, a ``.rq`` file or inline text (``source`` says which)."""

    name: str
    text: str
    source: str
    title: str = ""
    description: str = ""
    params: tuple[Param, ...] = ()
    examples: tuple[str, ...] = ()
    library: bool = False  # one of the shipped library's queries (found by name)

    def param(self, name: str) -> Param | None:
        return next((p for p in self.params if p.name == name), None)

    @property
    def needs_vocabulary(self) -> bool:
        """Whether the query may read the vocabulary graph (classes, labels, axioms).

        A throw-away store gets that graph (some 19k triples, most of a small program's query
        time) only when it may be read. Only library queries are judged by their text -- naming
        no RDFS, OWL, SKOS or Dublin Core term and taking no class parameter, they read programs
        and derived layers alone, and tests/test_query.py checks every one gives the same rows
        without it; any other query gets it.
        """
        if not self.library or any(p.type == "class" for p in self.params):
            return True
        return bool(_VOCABULARY_TERMS.search(self.text))


#: Prefixes and namespaces whose terms only the vocabulary graph holds.
_VOCABULARY_TERMS = re.compile(r"\b(rdfs|owl|skos|dcterms|dct):|rdf-schema#|/owl#|/skos/core#|purl\.org/dc/")


def parse_header(text: str, source: str) -> dict[str, Any]:
    """The ``# key: value`` lines at the top of a query (continuations are indented ``#`` lines)."""
    fields: dict[str, list[tuple[int, str]]] = {}
    last: str | None = None
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if not stripped.startswith("#"):
            break
        body = stripped[1:]
        match = re.match(r"^\s?([a-z]+):\s*(.*)$", body)
        if match and not body.startswith("   "):
            last = match.group(1)
            fields.setdefault(last, []).append((number, match.group(2).strip()))
        elif last is not None and body.strip():
            n, previous = fields[last][-1]
            fields[last][-1] = (n, f"{previous} {body.strip()}")
    params = []
    for number, value in fields.get("param", []):
        m = _PARAM.match(value)
        if m is None or m.group("type") not in PARAM_TYPES:
            raise QueryError(f"malformed parameter declaration {value!r}: expected 'name (type) = default -- "
                             f"description' with type one of {', '.join(PARAM_TYPES)}", source, number)
        params.append(Param(m.group("name"), m.group("type"), m.group("default"), (m.group("doc") or "").strip(),
                            number))
    return {"title": " ".join(v for _, v in fields.get("title", [])),
            "description": " ".join(v for _, v in fields.get("description", [])),
            "params": tuple(params), "examples": tuple(v for _, v in fields.get("example", []))}


def read_query(path: Path, name: str | None = None) -> Query:
    """A query file with its header."""
    text = path.read_text(encoding="utf-8")
    return Query(name or path.stem, text, str(path), **parse_header(text, str(path)))


def library(directory: Path | None = None) -> list[Query]:
    """Every query of the library (``queries/*.rq``), by name."""
    return [dataclasses.replace(read_query(p), library=True) for p in sorted((directory or queries_dir()).glob("*.rq"))]


def resolve(name_or_text: str, directory: Path | None = None) -> Query:
    """A library query by name, a ``.rq`` file by path, or SPARQL text."""
    folder = directory or queries_dir()
    if NAME.match(name_or_text):
        path = folder / f"{name_or_text}.rq"
        if path.is_file():
            return dataclasses.replace(read_query(path), library=True)
        names = [p.stem for p in sorted(folder.glob("*.rq"))]
        close = difflib.get_close_matches(name_or_text, names, n=3)
        raise QueryError(f"no library query {name_or_text!r}"
                         + (f"; did you mean {', '.join(close)}?" if close else "; `stepnc-graph queries` lists them"))
    if name_or_text.endswith(".rq") and "\n" not in name_or_text:
        path = Path(name_or_text)
        if not path.is_file():
            raise QueryError(f"no query file {name_or_text}")
        return read_query(path)
    return Query("-e", name_or_text, "-e", **parse_header(name_or_text, "-e"))


# -- parameters ------------------------------------------------------------------------------------


def _expand(value: str) -> str:
    """``prefix:local`` or ``<iri>`` or a bare IRI, as an IRI string."""
    if value.startswith("<") and value.endswith(">"):
        return value[1:-1]
    prefix, sep, local = value.partition(":")
    if sep and prefix in PREFIXES:
        return PREFIXES[prefix] + local
    return value


def _class_term(store: Store, value: str) -> ox.NamedNode:
    iri = _expand(value) if ":" in value else STEPNC_NS + value.lower()
    node = ox.NamedNode(iri)
    known = store.query(f"SELECT ?c WHERE {{ GRAPH <{VOCABULARY_GRAPH}> {{ ?c a <http://www.w3.org/2002/07/owl#Class> "
                        "FILTER(isIRI(?c)) } }")
    classes = {row["c"].value for row in known}
    if iri in classes:
        return node
    if not classes:
        raise ValueError("the store has no vocabulary graph to check classes against (load a file first)")
    names = sorted(c.removeprefix(STEPNC_NS) for c in classes if c.startswith(STEPNC_NS))
    close = difflib.get_close_matches(value.split(":")[-1].lower(), names, n=3)
    raise ValueError(f"no class {value!r} in the vocabulary" + (f"; did you mean {', '.join(close)}?" if close else ""))


def to_term(store: Store, type_: str, value: str) -> ox.NamedNode | ox.Literal:
    """``value`` (command-line text) as an RDF term of ``type_``; ValueError says what was expected."""
    if type_ == "class":
        return _class_term(store, value)
    if type_ == "iri":
        return ox.NamedNode(_expand(value))
    if type_ == "integer":
        if not re.fullmatch(r"[+-]?[0-9]+", value.strip()):
            raise ValueError(f"expected an integer, got {value!r}")
        return ox.Literal(value.strip(), datatype=ox.NamedNode(XSD + "integer"))
    if type_ == "decimal":
        try:
            Decimal(value.strip())
        except InvalidOperation:
            raise ValueError(f"expected a number, got {value!r}") from None
        return ox.Literal(value.strip(), datatype=ox.NamedNode(XSD + "decimal"))
    if type_ == "boolean":
        word = value.strip().lower()
        if word not in ("true", "false", "1", "0", "yes", "no"):
            raise ValueError(f"expected true or false, got {value!r}")
        return ox.Literal(word in ("true", "1", "yes"))
    return ox.Literal(value)


def _guess(value: str) -> str:
    """The type of an undeclared parameter's value: IRI, integer, decimal, boolean or string."""
    if value.startswith("<") or (":" in value and value.partition(":")[0] in PREFIXES):
        return "iri"
    if re.fullmatch(r"[+-]?[0-9]+", value):
        return "integer"
    if re.fullmatch(r"[+-]?([0-9]+\.[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?", value):
        return "decimal"
    if value in ("true", "false"):
        return "boolean"
    return "string"


def _param(name: str, value: str) -> str:
    """A parameter as the caller gave it: ``--param name=value``, or the keyword ``name='value'``."""
    return option("param", f"{name}={value}") if option("param").startswith("--") else f"{name}={value!r}"


def bind(store: Store, query: Query, given: Mapping[str, str]) -> dict[ox.Variable, ox.NamedNode | ox.Literal]:
    """The terms to substitute: declared parameters (given or default), and undeclared ones by their look."""
    out: dict[ox.Variable, ox.NamedNode | ox.Literal] = {}
    for name in given:
        if query.params and query.param(name) is None:
            raise QueryError(f"unknown parameter {name!r}; {query.name} takes "
                             f"{', '.join(p.name for p in query.params)}", query.source, parameter=name)
    for p in query.params:
        value = given[p.name] if p.name in given else p.default
        if value is None:
            raise QueryError(f"parameter {p.name} is required ({p.describe()})", query.source, p.line,
                             parameter=p.name)
        try:
            out[ox.Variable(p.name)] = to_term(store, p.type, value)
        except ValueError as exc:
            raise QueryError(f"{_param(p.name, value)}: {exc}", query.source, p.line, parameter=p.name) from None
    for name, value in given.items():
        if query.param(name) is None:
            try:
                out[ox.Variable(name)] = to_term(store, _guess(value), value)
            except ValueError as exc:
                raise QueryError(f"{_param(name, value)}: {exc}", query.source, parameter=name) from None
    return out


# -- results ---------------------------------------------------------------------------------------


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


# -- running ---------------------------------------------------------------------------------------


def _syntax_error(exc: SyntaxError, query: Query) -> QueryError:
    """A pyoxigraph syntax error as a positioned QueryError naming its cause (line, column, source
    line and caret; :mod:`.sparql_errors` finds the cause)."""
    text = str(exc)
    match = _POSITION.match(text)
    if match is None:
        return QueryError(f"SPARQL syntax error: {text}", query.source)
    cause = explain(query.text, int(match.group(1)), int(match.group(2)), match.group(3))
    message = cause.message
    if "Prefix not found" in message:
        message = (f"a prefix is not declared (predeclared: {', '.join(p + ':' for p in PREFIXES)}; "
                   "others need PREFIX)")
    lines = query.text.splitlines()
    excerpt = lines[cause.line - 1] if 0 < cause.line <= len(lines) else None
    return QueryError(f"SPARQL syntax error: {message}", query.source, cause.line, cause.column, excerpt=excerpt)


def dataset(store: Store, graph: str | None, library: bool = False) -> dict[str, Any]:
    """The query dataset: every graph as default graph and the graphs a user names (programs, link
    graphs) for GRAPH ?g, or one program's graph, its derived layer and the vocabulary.

    A ``library`` query over the whole store gets the store's own named graphs instead. Oxigraph evaluates a ``GRAPH ?g`` pattern over a
    list of named graphs one graph after the other -- a look-up per listed graph and row, so a
    whole-store query slows down with every program loaded -- and over the store's own graphs with
    one index look-up. The library is written so that this changes none of its rows: ``GRAPH ?g``
    holds a ``p21:id`` pattern (only files' graphs have one) or binds ``?g`` elsewhere first
    (tests/test_query.py runs every library query both ways).
    """
    if graph is None:
        if library:
            return {"use_default_graph_as_union": True}
        return {"use_default_graph_as_union": True, "named_graphs": [ox.NamedNode(g) for g in listed_graphs(store)]}
    if graph not in program_graphs(store):
        raise QueryError(f"no loaded file with graph {graph}; `stepnc-graph info` lists them")
    return {"default_graph": [ox.NamedNode(g) for g in (graph, derived_graph_iri(graph), VOCABULARY_GRAPH)],
            "named_graphs": [ox.NamedNode(graph)]}


def _warnings(store: Store, graph: str | None, vocabulary: bool = True) -> list[str]:
    out = []
    status = vocabulary_status(store) if vocabulary else "current"
    if status != "current":
        out.append(f"the store's vocabulary graph is {status}: load a file again to refresh it")
    graphs = [graph] if graph else program_graphs(store)
    missing = [g for g in graphs if not store.has_graph(derived_graph_iri(g))]
    if missing:
        out.append(f"no derived layer for {', '.join(missing)} (loaded by an older stepnc-graph): load it again")
    current = _current_layers(store)
    older = [g for g in graphs if g not in missing and g not in current]
    if older:
        out.append(f"the derived layer of {', '.join(older)} is from an older stepnc-graph (library queries miss "
                   "what it lacks): load it again")
    return out


def known_wrong_answers(store: Store, name: str) -> list[str]:
    """A warning for each behaviour of ``store`` known to change the rows of the library query
    ``name`` (the table of :mod:`stepnc_graph.store.behaviour`, by the store's ``Server`` header)."""
    return [f"{store.server} {b.does}: rows may be missing here; the embedded store (--store) answers exactly"
            for b in wrong_answers(store.server, name)]


#: a GROUP_CONCAT aggregate and the variable it is bound to
_GROUP_CONCAT = re.compile(r"GROUP_CONCAT\s*\((?:[^()]|\([^()]*\))*\)\s*AS\s+[?$](\w+)", re.IGNORECASE)


def concat_order_warnings(store: Store, text: str) -> list[str]:
    """A warning for a query whose ``GROUP_CONCAT`` lists come out in the store's own order.

    SPARQL leaves the order of a GROUP_CONCAT's values to the store (section 18.5.1.7); a query
    ordering its lists by an ordered sub-SELECT gets that order from the embedded store, not
    always from a store without :attr:`~stepnc_graph.store.contract.Capabilities.ordered_group_concat`:
    the same values, perhaps in another order, must not pass for the ordered answer. (The
    library's lists are built where Virtuoso keeps their order too: tests/test_live_stores.py.)"""
    if store.capabilities.ordered_group_concat:
        return []
    columns = sorted(set(_GROUP_CONCAT.findall(text)))
    if not columns:
        return []
    return [f"{store.server or 'this store'} does not keep the order of the values a GROUP_CONCAT joins (SPARQL "
            f"leaves it to the store): the values in {', '.join('?' + c for c in columns)} are right, their order "
            "inside each cell may not be the one the query asks for"]


def _current_layers(store: Store) -> set[str]:
    """The files whose derived layer is of the version the library expects (derive.LAYER_VERSION)."""
    from stepnc_graph.loading.derive import LAYER_VERSION

    rows = store.query(f"SELECT ?g WHERE {{ GRAPH ?layer {{ ?layer <{ANALYSIS_NS}layerOf> ?g ; "
                       f"<{ANALYSIS_NS}layerVersion> {LAYER_VERSION} }} }}")
    return {row[0].value for row in rows}


def refuse_service(query: Query, allow: bool = False) -> None:
    """Raise a QueryError if ``query`` would send a request to another server (a ``SERVICE``
    clause), unless ``allow`` (see :mod:`stepnc_graph.core.outbound`)."""
    try:
        refuse_outbound(query.text, allow=allow)
    except OutboundRefused as exc:
        raise QueryError(str(exc), query.source) from None


def execute(store: Store, query: Query, params: Mapping[str, str] | None = None,
            graph: str | None = None, *, allow_service: bool = False) -> QueryResult:
    """Run ``query`` with ``params`` (command-line strings) over the store or one file's ``graph``.

    A query with a ``SERVICE`` clause is refused (QueryError) unless ``allow_service``."""
    refuse_service(query, allow_service)
    if query.needs_vocabulary:
        vocabulary_for_queries(store)
    substitutions = bind(store, query, params or {})
    options = dataset(store, graph, query.library)
    try:
        result = store.query(query.text, prefixes=PREFIXES, substitutions=substitutions or None, **options)
    except SyntaxError as exc:
        raise _syntax_error(exc, query) from None
    except RuntimeError as exc:
        missing = re.search(r"variable \?(\w+) in its SELECT projection", str(exc))
        if missing:
            name = missing.group(1)
            declared = query.param(name)
            raise QueryError(f"parameter {name}: the query must SELECT ?{name} to take it as a parameter",
                             query.source, declared.line if declared else None, parameter=name) from None
        raise QueryError(f"query failed: {exc}", query.source) from None
    warnings = _warnings(store, graph, vocabulary=query.needs_vocabulary or not is_throwaway(store))
    if not query.library:  # the library's terms and lists are tested on each store; a user's are not
        warnings += term_warnings(store, query.text, PREFIXES, options)
        warnings += concat_order_warnings(store, query.text)
    else:
        warnings += known_wrong_answers(store, query.name)
    if isinstance(result, ox.QueryBoolean):
        return QueryResult("ask", boolean=bool(result), warnings=warnings,
                           _json=result.serialize(format=ox.QueryResultsFormat.JSON) or b"")
    if isinstance(result, ox.QueryTriples):
        return QueryResult("graph", triples=list(result), warnings=warnings)
    variables = [v.value for v in result.variables]
    data = result.serialize(format=ox.QueryResultsFormat.JSON) or b""
    return QueryResult("select", variables, warnings=warnings, _json=data)


def query(store: Store, name_or_text: str, *, graph: str | None = None, allow_service: bool = False,
          **params: Any) -> QueryResult:
    """Run a library query (by name), a ``.rq`` file or SPARQL text; keyword arguments are parameters.

        rows = query(store, "workingsteps-by-tool-type", tool_type="knurling_tool").rows

    ``allow_service`` lets a ``SERVICE`` clause send its request (refused otherwise).
    """
    return execute(store, resolve(name_or_text), {k: _text(v) for k, v in params.items()}, graph,
                   allow_service=allow_service)


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def describe_library(directory: Path | None = None) -> list[dict[str, Any]]:
    """The library as plain data (name, title, description, parameters, examples)."""
    return [{"name": q.name, "title": q.title, "description": q.description,
             "params": [{"name": p.name, "type": p.type, "default": p.default, "description": p.doc}
                        for p in q.params], "examples": list(q.examples)} for q in library(directory)]
