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

from stepnc_graph.generators.jsonld import context
from stepnc_graph.mapping.plan import iso14649_plans
from stepnc_graph.mapping.writer import write_graph
from stepnc_graph.naming import P21_NS
from stepnc_graph.schema.catalog import iso14649
from stepnc_graph.store import GraphStore, Store

FORMATS = ("ttl", "nt", "nq", "trig", "jsonld", "jsonld-tree", "p21")
_OX = {"ttl": ox.RdfFormat.TURTLE, "nt": ox.RdfFormat.N_TRIPLES, "nq": ox.RdfFormat.N_QUADS,
       "trig": ox.RdfFormat.TRIG}
QUAD_FORMATS = ("nq", "trig")


class ExportError(ValueError):
    """An export that cannot be done as asked (unknown graph, p21 of several graphs, ...)."""


def export(store: Store, fmt: str, graph: str | None = None) -> bytes:
    """Serialise one graph (``graph``) or the whole store (``None``) as ``fmt``.

    Triple formats (ttl, nt, jsonld of one graph, p21) need a graph unless the
    store holds exactly one; nq and trig keep graph names.
    """
    if fmt not in FORMATS:
        raise ExportError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
    if graph is not None and not store.has_graph(graph):
        raise ExportError(f"no graph {graph} in the store")
    if graph is None and fmt in ("ttl", "nt", "p21"):
        graphs = store.graphs()
        if len(graphs) != 1:
            raise ExportError(f"--format {fmt} writes one graph and the store has {len(graphs)}; choose one with "
                              f"--graph (see `stepnc-graph info`) or use nq/trig")
        graph = graphs[0]
    if fmt == "p21":
        assert graph is not None
        return write_graph(iso14649_plans(), store.quads(graph), graph).encode("utf-8")
    # the canonical order walks the graph node by node: a remote graph is copied here first
    local = store if isinstance(store, GraphStore) else store.local_copy(graph)  # type: ignore[attr-defined]
    if fmt in ("jsonld", "jsonld-tree"):
        return _jsonld(local, graph, fmt == "jsonld-tree")
    prefixes = context(iso14649()[0].naming)
    return _serialize(_OX[fmt], canonical_quads(local, graph), fmt not in QUAD_FORMATS, prefixes)


def _serialize(fmt: ox.RdfFormat, quads: Iterator[ox.Quad], triples: bool,
               prefixes: dict[str, str] | None = None) -> bytes:
    buffer = io.BytesIO()
    data: Iterator[ox.Quad] | Iterator[ox.Triple] = (
        (ox.Triple(q.subject, q.predicate, q.object) for q in quads) if triples else quads)
    keep = prefixes if prefixes and fmt in (ox.RdfFormat.TURTLE, ox.RdfFormat.TRIG) else None
    ox.serialize(data, buffer, fmt, prefixes=keep)
    return buffer.getvalue()


def canonical_quads(store: GraphStore, graph: str | None = None) -> Iterator[ox.Quad]:
    """The quads of ``graph`` (of every graph, in IRI order, for None) in the canonical order."""
    if graph is not None:
        yield from _graph_quads(store, graph)
        return
    db = store.oxigraph
    default = sorted(db.quads_for_pattern(None, None, None, ox.DefaultGraph()), key=str)
    yield from default
    for name in store.graphs():
        yield from _graph_quads(store, name)


def _object_key(term: object) -> tuple[int, str]:
    return (1, "") if isinstance(term, ox.BlankNode) else (0, str(term))


def _graph_quads(store: GraphStore, graph: str) -> Iterator[ox.Quad]:
    db = store.oxigraph
    g = ox.NamedNode(graph)
    numbered = sorted((int(str(q.object.value)), q.subject)  # type: ignore[union-attr]
                      for q in db.quads_for_pattern(None, ox.NamedNode(P21_NS + "id"), None, g))
    roots: list[tuple[str, Any]] = [("g", g)] + [(f"i{number}", node) for number, node in numbered]
    taken = {str(node) for _, node in roots}
    others = sorted((node for node in _named_subjects(store, graph) if str(node) not in taken), key=str)
    roots += [(f"n{k}", node) for k, node in enumerate(others, start=1)]
    blanks_seen: set[ox.BlankNode] = set()
    for prefix, node in roots:
        yield from _subtree(db, g, prefix, node, blanks_seen)
    # blank nodes no named subject reaches (none in loaded programs; SPARQL Update can add them)
    yield from sorted((q for q in db.quads_for_pattern(None, None, None, g)
                       if isinstance(q.subject, ox.BlankNode) and q.subject not in blanks_seen), key=str)


def _named_subjects(store: GraphStore, graph: str) -> list[ox.NamedNode]:
    """The named subjects of the graph that are not numbered instances (metadata, aliases, sections)."""
    rows = store.query(f"SELECT DISTINCT ?s WHERE {{ GRAPH {ox.NamedNode(graph)} {{ ?s ?p ?o "
                       f"FILTER(isIRI(?s) && NOT EXISTS {{ ?s <{P21_NS}id> ?i }}) }} }}")
    return [row[0] for row in rows]


def _subtree(db: ox.Store, g: ox.NamedNode, prefix: str, root: ox.NamedNode | ox.BlankNode,
             blanks_seen: set[ox.BlankNode]) -> Iterator[ox.Quad]:
    """``root``'s quads sorted, then its blank objects' (depth first), relabelled ``_:<prefix>b<n>``."""
    labels: dict[ox.BlankNode, ox.BlankNode] = {}

    def label(node: object) -> object:
        if not isinstance(node, ox.BlankNode):
            return node
        if node not in labels:
            labels[node] = ox.BlankNode(f"{prefix}b{len(labels) + 1}")
        return labels[node]

    stack: list[ox.NamedNode | ox.BlankNode] = [root]
    while stack:
        subject = stack.pop()
        quads = sorted(db.quads_for_pattern(subject, None, None, g),
                       key=lambda q: (q.predicate.value, _object_key(q.object), _shallow(db, g, q.object)))
        children = []
        for q in quads:
            if isinstance(q.object, ox.BlankNode) and q.object not in blanks_seen:
                blanks_seen.add(q.object)
                label(q.object)
                children.append(q.object)
        for q in quads:
            yield ox.Quad(label(q.subject), q.predicate, label(q.object), g)  # type: ignore[arg-type]
        stack.extend(reversed(children))


def _shallow(db: ox.Store, g: ox.NamedNode, term: object) -> str:
    """A blank node's own triples without blank labels: orders blank siblings (SET members that
    are typed values) the same way whatever labels Oxigraph gave them."""
    if not isinstance(term, ox.BlankNode):
        return ""
    return "\n".join(sorted(f"{q.predicate} {'[]' if isinstance(q.object, ox.BlankNode) else q.object}"
                            for q in db.quads_for_pattern(term, None, None, g)))


def _jsonld(store: GraphStore, graph: str | None, tree: bool = False) -> bytes:
    """JSON-LD compacted with the generated context (``tree``: a readable, framed tree); see
    :mod:`stepnc_graph.jsonld`."""
    from stepnc_graph.jsonld import export_jsonld

    return export_jsonld(canonical_quads(store, graph), graph, tree)
