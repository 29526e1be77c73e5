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

Results: :class:`QueryResult` (:mod:`stepnc_graph.querying.results`, re-exported here with
the prefixes and :class:`QueryError`); ``csv``, ``tsv`` and ``json`` are the SPARQL 1.1 results
formats, written by Oxigraph's own serialisers.
"""

from __future__ import annotations

import dataclasses
import difflib
import re
from collections.abc import Mapping
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyoxigraph as ox

from stepnc_graph.core.naming import (
    ANALYSIS_NS,
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

from stepnc_graph.querying.results import (
    DISPLAY_PREFIXES as DISPLAY_PREFIXES,
    FORMATS as FORMATS,
    PREFIXES as PREFIXES,
    RDF_FORMATS as RDF_FORMATS,
    XSD as XSD,
    QueryError as QueryError,
    QueryResult as QueryResult,
    formula_guard as formula_guard,
)
from stepnc_graph.querying.sparql_errors import explain
from stepnc_graph.querying.terms import term_warnings
from stepnc_graph.store.behaviour import wrong_answers


if TYPE_CHECKING:
    from stepnc_graph.store.contract import Store

PARAM_TYPES = ("class", "iri", "string", "integer", "decimal", "boolean")
NAME = re.compile(r"^[a-z0-9][a-z0-9-]*$")
_PARAM = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*\((?P<type>[a-z]+)\)\s*"
                    r"(?:=\s*(?P<default>.*?))?\s*(?:--\s*(?P<doc>.*))?$")
_POSITION = re.compile(r"error at (\d+):(\d+): (.*)", re.S)


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
    """``value`` as a class of the vocabulary graph; ValueError with the closest names if it is none.

    A known class costs one look-up (``ASK``); the vocabulary's classes (some 1,500, each IRI read
    from the store's string table: 7-11 ms on a 100k store, most of a ``--graph`` query with a class
    parameter) are listed only to suggest names for an unknown one."""
    iri = _expand(value) if ":" in value else STEPNC_NS + value.lower()
    node = ox.NamedNode(iri)
    if bool(store.query(f"ASK {{ GRAPH <{VOCABULARY_GRAPH}> {{ {node} a <http://www.w3.org/2002/07/owl#Class> }} }}")):
        return node
    known = store.query(f"SELECT ?c WHERE {{ GRAPH <{VOCABULARY_GRAPH}> {{ ?c a <http://www.w3.org/2002/07/owl#Class> "
                        "FILTER(isIRI(?c)) } }")
    classes = {row["c"].value for row in known}
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


def dataset(store: Store, graph: str | None, library: bool = False, vocabulary: bool = False) -> dict[str, Any]:
    """The query dataset: every graph as default graph and the graphs a user names (programs, link
    graphs) for GRAPH ?g, or one program's graph, its derived layer and the vocabulary.

    The vocabulary graph is a named graph too for a query that names it (``vocabulary``:
    ``GRAPH <.../iso14649> { ?c rdfs:subClassOf* ?super }``) and for every library query: with
    ``graph``, the default graph is three graphs and each index look-up there is one per graph --
    three per step of a path over the classes, each dearer the larger the store -- where inside
    ``GRAPH <vocabulary>`` it is one (``instance-counts``).

    A ``library`` query over the whole store gets the store's own named graphs instead. Oxigraph evaluates a ``GRAPH ?g`` pattern over a
    list of named graphs one graph after the other -- a look-up per listed graph and row, so a
    whole-store query slows down with every program loaded -- and over the store's own graphs with
    one index look-up. The library is written so that this changes none of its rows: ``GRAPH ?g``
    holds a ``p21:id`` pattern (only files' graphs have one) or binds ``?g`` elsewhere first
    (tests/test_query.py runs every library query both ways).
    """
    vocabulary_named = [VOCABULARY_GRAPH] if library or vocabulary else []
    if graph is None:
        if library:
            return {"use_default_graph_as_union": True}
        return {"use_default_graph_as_union": True,
                "named_graphs": [ox.NamedNode(g) for g in [*listed_graphs(store), *vocabulary_named]]}
    if graph not in program_graphs(store):
        raise QueryError(f"no loaded file with graph {graph}; `stepnc-graph info` lists them")
    named = [graph, *vocabulary_named]
    return {"default_graph": [ox.NamedNode(g) for g in (graph, derived_graph_iri(graph), VOCABULARY_GRAPH)],
            "named_graphs": [ox.NamedNode(g) for g in named]}


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
    """What ``store`` is known to do wrong with the rows of the library query ``name`` (the table
    of :mod:`stepnc_graph.store.behaviour`, by the store's ``Server`` header), one sentence each."""
    return [f"{store.server} {b.does}" for b in wrong_answers(store.server, name)]


def _graphs_read(store: Store, graph: str | None) -> list[str] | None:
    """The graphs of :func:`dataset` a library query over ``graph`` reads that the store holds (one
    program's graph, its derived layer and the vocabulary); None (every graph) for the whole store."""
    if graph is None:
        return None
    return [g.value for g in dataset(store, graph, library=True)["default_graph"] if store.has_graph(g.value)]


def _answered_from_a_copy(store: Store, query: Query, params: Mapping[str, str] | None, graph: str | None,
                          known: list[str]) -> QueryResult:
    """``query`` answered by the embedded engine over an in-memory copy of the graphs it reads,
    for a library query the remote ``store`` is known to answer with rows missing.

    Such a store's rows cannot be corrected afterwards (which rows it drops depends on its data),
    so its answer is not used at all: the graphs are read with the Graph Store Protocol (what
    ``export`` and ``validate`` do) and the query runs here, with the rows the embedded store
    gives. The answer says so: the copy costs a read of those graphs, the whole store's for a
    whole-store query."""
    copy = store.local_copy(_graphs_read(store, graph))
    try:
        result = execute(copy, query, params, graph)
    finally:
        copy.close()
    scope = "every graph of the store" if graph is None else f"the graphs of {graph}"
    result.warnings += [f"{what}: answered by stepnc-graph's own engine over a copy of {scope}, read from the "
                        "store, instead of by the store" for what in known]
    return result


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
    known = known_wrong_answers(store, query.name) if query.library else []
    if known and not store.capabilities.local_reads:
        return _answered_from_a_copy(store, query, params, graph, known)
    if query.needs_vocabulary:
        vocabulary_for_queries(store)
    substitutions = bind(store, query, params or {})
    options = dataset(store, graph, query.library, vocabulary=f"<{VOCABULARY_GRAPH}>" in query.text)
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
