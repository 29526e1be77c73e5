"""Export graphs of the store: RDF serialisations and Part 21.

Exports are deterministic -- the same graph gives the same bytes -- so that a
PLM system diffing two exports of a program sees only real changes. Oxigraph
gives blank nodes random labels when it loads, and dumps in the order of its
internal (hashed) ids, so RDF exports are written here in a canonical order:
the graph's own node, then each instance in ``#id`` order with the blank
nodes hanging off it (its lists and typed values) labelled by the instance and
their place (``_:i12b3``), then the other named subjects sorted.
"""

from __future__ import annotations

import io
from collections.abc import Iterator
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.errors import listed_by, option
from stepnc_graph.generators.context import context
from stepnc_graph.mapping.plans import iso14649_plans
from stepnc_graph.mapping.writer import write_graph
from stepnc_graph.core.naming import P21_NS
from stepnc_graph.schema.catalog import iso14649
from stepnc_graph.store import GraphStore, Store, program_graphs

FORMATS = ("ttl", "nt", "nq", "trig", "jsonld", "jsonld-tree", "p21")
_OX = {"ttl": ox.RdfFormat.TURTLE, "nt": ox.RdfFormat.N_TRIPLES, "nq": ox.RdfFormat.N_QUADS,
       "trig": ox.RdfFormat.TRIG}
QUAD_FORMATS = ("nq", "trig")


class ExportError(ValueError):
    """An export that cannot be done as asked (unknown graph, p21 of several graphs, ...)."""


def export(store: Store, fmt: str, graph: str | None = None) -> bytes:
    """Serialise one graph (``graph``) or the store's loaded graphs (``None``) as ``fmt``.

    One rule for every format: without ``graph`` an export holds the graphs a user names -- the
    programs, their link graphs and graphs users added (:meth:`GraphStore.graphs`) -- never the
    vocabulary graph or the derived layers, which a load writes again (name one with ``graph``
    to export it). Triple formats (ttl, nt, p21) hold one graph, so without ``graph`` they need a
    store of one program (that program's graph); nq, trig and jsonld keep graph names.
    """
    if fmt not in FORMATS:
        raise ExportError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
    if graph is not None and not store.has_graph(graph):
        raise ExportError(f"no graph {graph} in the store")
    if graph is None and fmt in ("ttl", "nt", "p21"):
        programs = program_graphs(store)
        if len(programs) != 1:
            raise ExportError(f"{fmt} writes one graph and the store holds {len(programs)} programs; "
                              f"choose one with {option('graph')} ({listed_by()}) or use nq, trig or "
                              "jsonld")
        graph = programs[0]
    if fmt == "p21":
        assert graph is not None
        return write_graph(iso14649_plans(), store.quads(graph), graph).encode("utf-8")
    graphs = None if graph is not None else store.graphs()
    # the canonical order walks the graph node by node: a remote graph is copied here first
    local = store if isinstance(store, GraphStore) else store.local_copy(graph or graphs)  # type: ignore[attr-defined]
    if fmt in ("jsonld", "jsonld-tree"):
        return _jsonld(local, graph, graphs, fmt == "jsonld-tree")
    prefixes = context(iso14649()[0].naming)
    return _serialize(_OX[fmt], canonical_quads(local, graph, graphs), fmt not in QUAD_FORMATS, prefixes)


def _serialize(fmt: ox.RdfFormat, quads: Iterator[ox.Quad], triples: bool,
               prefixes: dict[str, str] | None = None) -> bytes:
    buffer = io.BytesIO()
    data: Iterator[ox.Quad] | Iterator[ox.Triple] = (
        (ox.Triple(q.subject, q.predicate, q.object) for q in quads) if triples else quads)
    keep = prefixes if prefixes and fmt in (ox.RdfFormat.TURTLE, ox.RdfFormat.TRIG) else None
    ox.serialize(data, buffer, fmt, prefixes=keep)
    return buffer.getvalue()


def canonical_quads(store: GraphStore, graph: str | None = None,
                    graphs: list[str] | None = None) -> Iterator[ox.Quad]:
    """The quads of ``graph`` in the canonical order; for None, of ``graphs`` (default: every
    graph, the vocabulary and derived layers included, and the default graph), in IRI order.

    A blank node keeps one label across graphs (a derived layer's ``sga:index`` is on the list
    cells of its program graph), so whole-store labels carry the graph's place as well.
    """
    labels = _Labels()
    if graph is not None:
        yield from _graph_quads(store, graph, labels, "")
        return
    if graphs is None:
        db = store.oxigraph
        yield from sorted(db.quads_for_pattern(None, None, None, ox.DefaultGraph()), key=str)
    for k, name in enumerate(graphs if graphs is not None else store.all_graphs(), start=1):
        yield from _graph_quads(store, name, labels, f"g{k}")


class _Labels:
    """Canonical blank node labels: ``<scope><root>b<n>``, one per node for a whole export."""

    def __init__(self) -> None:
        self.of: dict[ox.BlankNode, ox.BlankNode] = {}
        self.used: dict[str, int] = {}

    def label(self, node: object, prefix: str) -> object:
        if not isinstance(node, ox.BlankNode):
            return node
        if node not in self.of:
            self.used[prefix] = self.used.get(prefix, 0) + 1
            self.of[node] = ox.BlankNode(f"{prefix}b{self.used[prefix]}")
        return self.of[node]


def _object_key(term: object) -> tuple[int, str]:
    return (1, "") if isinstance(term, ox.BlankNode) else (0, str(term))


def _graph_quads(store: GraphStore, graph: str, labels: _Labels, scope: str) -> Iterator[ox.Quad]:
    db = store.oxigraph
    g = ox.NamedNode(graph)
    numbered = sorted((int(str(q.object.value)), q.subject)  # type: ignore[union-attr]
                      for q in db.quads_for_pattern(None, ox.NamedNode(P21_NS + "id"), None, g))
    roots: list[tuple[str, Any]] = [("g", g)] + [(f"i{number}", node) for number, node in numbered]
    taken = {str(node) for _, node in roots}
    others = sorted((node for node in _named_subjects(store, graph) if str(node) not in taken), key=str)
    roots += [(f"n{k}", node) for k, node in enumerate(others, start=1)]
    seen: set[ox.BlankNode] = set()
    for prefix, node in roots:
        yield from _subtree(db, g, scope + prefix, node, seen, labels)
    # blank subjects no named subject of this graph reaches: the cells a derived layer indexes
    # (labelled in their program graph), or what SPARQL Update added (labelled by content)
    rest = {q.subject for q in db.quads_for_pattern(None, None, None, g)
            if isinstance(q.subject, ox.BlankNode) and q.subject not in seen}
    known = sorted((n for n in rest if n in labels.of), key=lambda n: labels.of[n].value)
    unknown = sorted((n for n in rest if n not in labels.of), key=lambda n: _deep(db, g, n))
    for node in known + unknown:
        if node not in seen:
            yield from _subtree(db, g, scope + "x", node, seen, labels)


def _named_subjects(store: GraphStore, graph: str) -> list[ox.NamedNode]:
    """The named subjects of the graph that are not numbered instances (metadata, aliases, sections)."""
    rows = store.query(f"SELECT DISTINCT ?s WHERE {{ GRAPH {ox.NamedNode(graph)} {{ ?s ?p ?o "
                       f"FILTER(isIRI(?s) && NOT EXISTS {{ ?s <{P21_NS}id> ?i }}) }} }}")
    return [row[0] for row in rows]


def _subtree(db: ox.Store, g: ox.NamedNode, prefix: str, root: ox.NamedNode | ox.BlankNode,
             seen: set[ox.BlankNode], labels: _Labels) -> Iterator[ox.Quad]:
    """``root``'s quads sorted, then its blank objects' (depth first), relabelled ``_:<prefix>b<n>``."""
    if isinstance(root, ox.BlankNode):
        seen.add(root)
        labels.label(root, prefix)
    stack: list[ox.NamedNode | ox.BlankNode] = [root]
    while stack:
        subject = stack.pop()
        quads = sorted(db.quads_for_pattern(subject, None, None, g),
                       key=lambda q: (q.predicate.value, _object_key(q.object), _shallow(db, g, q.object)))
        children = []
        for q in quads:
            if isinstance(q.object, ox.BlankNode) and q.object not in seen:
                seen.add(q.object)
                labels.label(q.object, prefix)
                children.append(q.object)
        for q in quads:
            yield ox.Quad(labels.label(q.subject, prefix), q.predicate, labels.label(q.object, prefix),  # type: ignore[arg-type]
                          g)
        stack.extend(reversed(children))


def _deep(db: ox.Store, g: ox.NamedNode, node: ox.BlankNode, limit: int = 500) -> str:
    """A blank node's content down through its blank objects, without labels (up to ``limit``
    nodes): orders the blank subjects no named subject reaches, such as OWL's
    ``[ a owl:AllDisjointClasses ; owl:members (...) ]``."""
    lines: list[str] = []
    stack: list[tuple[str, ox.BlankNode]] = [("", node)]
    visited = 0
    while stack and visited < limit:
        path, current = stack.pop()
        visited += 1
        for q in sorted(db.quads_for_pattern(current, None, None, g), key=lambda q: (q.predicate.value, str(q.object))):
            if isinstance(q.object, ox.BlankNode):
                stack.append((f"{path}/{q.predicate.value}", q.object))
            else:
                lines.append(f"{path} {q.predicate} {q.object}")
    return "\n".join(sorted(lines))


def _shallow(db: ox.Store, g: ox.NamedNode, term: object) -> str:
    """A blank node's own triples without blank labels: orders blank siblings (SET members that
    are typed values) the same way whatever labels Oxigraph gave them."""
    if not isinstance(term, ox.BlankNode):
        return ""
    return "\n".join(sorted(f"{q.predicate} {'[]' if isinstance(q.object, ox.BlankNode) else q.object}"
                            for q in db.quads_for_pattern(term, None, None, g)))


def _jsonld(store: GraphStore, graph: str | None, graphs: list[str] | None, tree: bool = False) -> bytes:
    """JSON-LD compacted with the generated context (``tree``: a readable, framed tree); see
    :mod:`stepnc_graph.exporting.jsonld`."""
    from stepnc_graph.exporting.jsonld import export_jsonld

    return export_jsonld(canonical_quads(store, graph, graphs), graph, tree)
