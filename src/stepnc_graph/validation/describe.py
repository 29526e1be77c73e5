"""Raw rows of the checks as results: the Part 21 #id, line and entity of focus nodes and values,
messages (the shape's, or the component's default) and rules; and results of the loader's
diagnostics and of ill-typed literals."""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence

import pyoxigraph as ox

from stepnc_graph.core.naming import P21_NS, instance_id
from stepnc_graph.part21.diagnostics import Diagnostic
from stepnc_graph.validation import components as C
from stepnc_graph.validation.compiled import CompiledShapes
from stepnc_graph.validation.engine import Check
from stepnc_graph.validation.runner import Row
from stepnc_graph.validation.report import SEVERITIES, Result
from stepnc_graph.validation.shapes import RDF_FIRST, RDF_TYPE, SH, ShapesGraph, literal_text, sh

SHAPES_NS = "https://w3id.org/stepnc-graph/shapes#"
STEPNC_NS = "https://w3id.org/stepnc-graph/iso14649#"
RDFS_LABEL = "<http://www.w3.org/2000/01/rdf-schema#label>"
RDFS_COMMENT = "<http://www.w3.org/2000/01/rdf-schema#comment>"


def ill_typed_result(graph: str, bad: object) -> Result:
    from stepnc_graph.validation.rdfdata import IllTyped

    assert isinstance(bad, IllTyped)
    lexical = literal_text(bad.literal)
    datatype = bad.literal.rsplit("^^", 1)[-1]
    return Result("Violation", graph, bad.subject.strip("<>"), None, None, None, _readable_path(bad.predicate), lexical,
                  f"{lexical!r} is not a valid {_local(datatype)} literal", None, None, "loader:RDF-ILL-TYPED",
                  path_iri=bad.predicate, value_term=bad.literal, focus_term=bad.subject)


#: a loader diagnostic's severity as a result's: an error fails the program, a warning (a
#: recovered syntax slip, a remark skipped) or an info only informs, as the loader said
_DIAGNOSTIC_SEVERITY = {"error": "Violation", "warning": "Warning", "info": "Info"}


def diagnostic_result(graph: str, d: Diagnostic) -> Result:
    """A loader diagnostic of a file validated here as a result of its own severity."""
    from stepnc_graph.core.naming import instance_iri

    focus = instance_iri(graph, d.p21_id) if d.p21_id is not None else graph
    return Result(_DIAGNOSTIC_SEVERITY[d.severity], graph, focus, d.p21_id, None, d.line, None, None, d.message,
                  d.code, "ISO 10303-21", f"loader:{d.code}")


def _readable_path(path: str) -> str:
    """``<...#entity.attr>/<...#e2.attr2>`` as ``attr/attr2``: attribute names, other IRIs by local name."""
    text = re.sub(rf"<{re.escape(STEPNC_NS)}[^.>]*\.([^>]*)>", r"\1", path)
    text = re.sub(r"<[^>]*[#/]([^>#/]*)>", r"\1", text)
    return text[1:-1] if text.startswith("(") and text.endswith(")") and text.count("(") == 1 else text


#: component IRI -> component, for default messages
_COMPONENTS: dict[str, C.Component] = {comp.iri: comp for comp in C.REGISTRY}


def _severity(term: str) -> str:
    """sh:Violation, sh:Warning, sh:Info by name; any other severity IRI in full (SHACL 2.1.6)."""
    iri = term.strip("<>")
    return iri[len(SH):] if iri.startswith(SH) and iri[len(SH):] in SEVERITIES else iri


def _preferred(messages: Sequence[str]) -> str:
    """The message to show: one without a language tag, else English, else the first."""
    if not messages:
        return ""
    plain = [m for m in messages if m.endswith('"') or '"^^' in m]
    english = [m for m in messages if re.search(r'"@en(-[A-Za-z]+)?$', m)]
    return literal_text((plain or english or list(messages))[0])


def _local(term: str) -> str:
    """A readable name for a term: the local name of a vocabulary IRI."""
    if term.startswith("<") and term.endswith(">"):
        iri = term[1:-1]
        for ns in (STEPNC_NS, SHAPES_NS, P21_NS, SH, "http://www.w3.org/2001/XMLSchema#"):
            if iri.startswith(ns):
                return iri[len(ns):]
        return iri
    return term


class Describer:
    """Turns raw rows into results: Part 21 #id, line and entity of focus nodes and values, messages.

    ``lines`` (#id -> line) stands in for the ``p21:id``/``p21:line`` triples of a
    graph loaded without them (:attr:`~stepnc_graph.loading.loader.LoadResult.lines`)."""

    def __init__(self, store: ox.Store, graph: str, shapes: CompiledShapes,
                 lines: Mapping[int, int] | None = None) -> None:
        self.store = store
        self.graph = graph
        self.shapes = shapes
        self.lines = lines
        self.info: dict[str, tuple[int | None, int | None, str | None]] = {}
        self._g: ShapesGraph | None = None

    @property
    def g(self) -> ShapesGraph:
        return self._g if self._g is not None else self.shapes.graph

    def lookup(self, terms: Iterable[str]) -> None:
        """#id, line and entity name of instance IRIs, in one query."""
        wanted = sorted({t for t in terms if t.startswith("<") and t not in self.info})
        for start in range(0, len(wanted), 2000):
            found = self._positions(wanted[start:start + 2000])
            for key, (ident, line, types) in found.items():
                self.info[key] = (ident, line, "+".join(sorted(types)) or None)

    def _positions(self, terms: list[str]) -> dict[str, tuple[int, int, list[str]]]:
        """#id, line and type names of the instance IRIs among ``terms`` (``<iri>`` texts)."""
        g = ox.NamedNode(self.graph)
        found: dict[str, tuple[int, int, list[str]]] = {}
        if self.lines is None:
            rows = self.store.query(f"SELECT ?s ?id ?line ?t WHERE {{ VALUES ?s {{ {' '.join(terms)} }} ?s <{P21_NS}id> ?id ; "
                                    f"<{P21_NS}line> ?line . OPTIONAL {{ ?s a ?t }} }}", default_graph=g)
            for r in rows:  # type: ignore[union-attr]
                entry = found.setdefault(str(r[0]), (int(r[1].value), int(r[2].value), []))
                if r[3] is not None:
                    entry[2].append(_local(str(r[3])))
            return found
        for term in terms:
            ident = instance_id(self.graph, term[1:-1])
            if ident is not None and ident in self.lines:
                found[term] = (ident, self.lines[ident], [])
        if found:
            rows = self.store.query(f"SELECT ?s ?t WHERE {{ VALUES ?s {{ {' '.join(found)} }} ?s a ?t }}",
                                    default_graph=g)
            for r in rows:  # type: ignore[union-attr]
                found[str(r[0])][2].append(_local(str(r[1])))
        return found

    def owner(self, node: ox.BlankNode) -> str | None:
        """The instance holding a blank node (a list cell or typed value)."""
        current: object = node
        g = ox.NamedNode(self.graph)
        for _ in range(10000):
            holder = next(iter(self.store.quads_for_pattern(None, None, current, g)), None)  # type: ignore[arg-type]
            if holder is None:
                return None
            current = holder.subject
            if isinstance(current, ox.NamedNode):
                return str(current)
        return None

    def results(self, rows: list[Row]) -> list[Result]:
        self._g = self.shapes.describing({p for r in rows for p in r.check.files}) if rows else None
        focus_terms = {str(r.focus) if not isinstance(r.focus, ox.BlankNode) else self.owner(r.focus) or "" for r in rows}
        self.lookup(focus_terms | {str(r.value) for r in rows if isinstance(r.value, ox.NamedNode)})
        return [self.result(r) for r in rows]

    def result(self, row: Row) -> Result:
        c = row.check
        focus = str(row.focus)
        where = self.owner(row.focus) if isinstance(row.focus, ox.BlankNode) else focus
        ident, line, entity = self.info.get(where or "", (None, None, None))
        shape = c.shape
        labels = (shape, c.parent) if c.parent else (shape,)
        clause = next((literal_text(v) for s in labels if (v := self.g.value(s, f"<{P21_NS}isoClause>"))), None)
        value = self.describe(row.value) if row.value is not None else None
        path_sparql: str | None
        path_term: str | None
        if row.path is not None:  # sh:closed, or a SPARQL solution's ?path
            path_sparql = path_term = str(row.path)
        else:
            path_sparql, path_term = c.path, c.path_term
        path = _readable_path(path_sparql) if path_sparql else None
        messages = self.messages(row, value)
        return Result(
            severity=_severity(c.severity), graph=self.graph, focus=focus.strip("<>"), p21_id=ident, entity=entity,
            line=line, path=path, value=value, message=_preferred(messages), rule=self.rule(c),
            clause=clause, component=c.component.strip("<>"), shape=shape.strip("<>") if shape.startswith("<") else None,
            path_iri=path_sparql,
            value_term=str(row.value) if row.value is not None else None,
            focus_term=focus, shape_term=shape, path_term=path_term,
            path_turtle=self.path_turtle(path_term) if path_term else None, message_terms=tuple(messages))

    def path_turtle(self, term: str, depth: int = 0) -> str:
        """A SHACL path node of the shapes graph written as Turtle (blank nodes nested)."""
        if not term.startswith("_:") or depth > 20:
            return term
        if self.g.value(term, RDF_FIRST) is not None:
            return "( " + " ".join(self.path_turtle(t, depth + 1) for t in self.g.items(term)) + " )"
        parts = [f"{p} {self.path_turtle(o, depth + 1)}" for p in self.g.predicates(term) for o in self.g.objects(term, p)]
        return "[ " + " ; ".join(parts) + " ]"

    def describe(self, value: object) -> str:
        text = str(value)
        if isinstance(value, ox.Literal):
            return value.value
        if text in self.info:
            ident, _, entity = self.info[text]
            return f"#{ident} {(entity or '').upper()}".strip()
        if isinstance(value, ox.BlankNode):
            return "a list or typed value"
        return _local(text)

    def rule(self, c: Check) -> str | None:
        for s in (c.shape, c.parent):
            if s is None:
                continue
            label = self.g.value(s, f"<{SHAPES_NS}rule>")
            text = self.g.value(s, f"<{SHAPES_NS}expressText>")
            name = self.g.value(s, RDFS_LABEL)
            if label and text and name:
                return f"{literal_text(name)}: {literal_text(text)}"
            kind = self.g.value(s, f"<{P21_NS}expressType>")
            if name and kind:
                return f"{literal_text(name)} : {literal_text(kind)}"
            if name:
                return literal_text(name)
        return None

    def messages(self, row: Row, value: str | None) -> list[str]:
        """The result's messages as literals (N-Triples): the SPARQL constraint's or validator's
        sh:message, else the shape's (SHACL 2.1.5), ``{$var}``/``{?var}`` replaced by the
        solution's bindings or the component's parameters; else the component's own text."""
        c = row.check
        for s in (c.sparql_node, c.shape):
            own = self.g.objects(s, sh("message")) if s else []
            if own:
                return [self.fill(m, row) for m in own]
        args = dict(c.args)
        component = _COMPONENTS.get(c.component.strip("<>"))
        text = component.message(self.g, args, value, c.shape) if component is not None and args else \
            f"{_local(c.component)} not satisfied{f', found {value}' if value is not None else ''}"
        return ['"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"']

    def fill(self, message: str, row: Row) -> str:
        """``{$name}`` and ``{?name}`` in a message literal replaced by the value they name."""
        values: dict[str, str] = {"this": str(row.focus)}
        if row.value is not None:
            values["value"] = str(row.value)
        if row.path is not None:
            values["path"] = str(row.path)
        values.update(row.check.args)
        values.update((k, str(v)) for k, v in row.bindings)

        def sub(m: re.Match[str]) -> str:
            term = values.get(m.group(1))
            if term is None:
                return m.group(0)
            shown = literal_text(term) if term.startswith('"') else term.strip("<>")
            return shown.replace("\\", "\\\\").replace('"', '\\"')

        return re.sub(r"\{[$?]([A-Za-z_][\w]*)\}", sub, message)

    def raw_instances(self) -> list[Result]:
        """Instances the loader kept raw (a store validated without its load's diagnostics)."""
        rows = self.store.query(
            f"SELECT ?s ?id ?line ?name WHERE {{ ?s {RDF_TYPE} <{P21_NS}RawInstance> ; <{P21_NS}id> ?id ; "
            f"<{P21_NS}line> ?line . OPTIONAL {{ ?s <{P21_NS}entityName> ?name }} }}",
            default_graph=ox.NamedNode(self.graph))
        out = []
        for r in rows:  # type: ignore[union-attr]
            name = r[3].value if r[3] is not None else None
            out.append(Result("Violation", self.graph, r[0].value, int(r[1].value), name, int(r[2].value), None,
                              None, "kept raw by the loader: it does not fit the schema (load it again to see why)",
                              "P21 raw instance", "ISO 10303-21", "loader:P21-RAW"))
        return out
