"""Export graphs of the store: RDF serialisations and Part 21."""

from __future__ import annotations

import json

import pyoxigraph as ox

from stepnc_graph.generators.jsonld import context
from stepnc_graph.mapping.plan import iso14649_plans
from stepnc_graph.mapping.writer import write_graph
from stepnc_graph.resources import ontology_dir
from stepnc_graph.schema.catalog import iso14649
from stepnc_graph.store import GraphStore

FORMATS = ("ttl", "nt", "nq", "trig", "jsonld", "p21")
_OX = {"ttl": ox.RdfFormat.TURTLE, "nt": ox.RdfFormat.N_TRIPLES, "nq": ox.RdfFormat.N_QUADS,
       "trig": ox.RdfFormat.TRIG}
QUAD_FORMATS = ("nq", "trig")


class ExportError(ValueError):
    """An export that cannot be done as asked (unknown graph, p21 of several graphs, ...)."""


def export(store: GraphStore, fmt: str, graph: str | None = None) -> bytes:
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
    if fmt == "jsonld":
        return _jsonld(store, graph)
    prefixes = context(iso14649()[0].naming)
    return store.dump(_OX[fmt], None if fmt in QUAD_FORMATS and graph is None else graph, prefixes)


def _jsonld(store: GraphStore, graph: str | None) -> bytes:
    """Compact JSON-LD with the shipped context (``ontology/context.jsonld``)."""
    import rdflib

    data = store.dump(ox.RdfFormat.N_QUADS, None) if graph is None else store.dump(ox.RdfFormat.N_TRIPLES, graph)
    if graph is None:
        ds = rdflib.Dataset()
        ds.parse(data=data.decode("utf-8"), format="nquads")
        target: rdflib.Graph = ds
    else:
        target = rdflib.Graph(identifier=rdflib.URIRef(graph))
        target.parse(data=data.decode("utf-8"), format="nt")
    ctx = json.loads((ontology_dir() / "context.jsonld").read_text())["@context"]
    return target.serialize(format="json-ld", context=ctx, auto_compact=True).encode("utf-8")
