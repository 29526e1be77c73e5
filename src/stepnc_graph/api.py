"""The Python API: the same operations as the command line.

    import stepnc_graph as sg
    store = sg.open_store(memory=True)
    [result] = sg.load(store, ["part.stp"], lenient=True)
    print(result.instances, result.triples, result.diagnostics)
    turtle = sg.export(store, "ttl", result.graph)
    rows = sg.query(store, "tool-changes").rows     # a library query; keyword arguments are parameters
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from stepnc_graph.export import export
from stepnc_graph.loader import LoadResult, Progress, load_file
from stepnc_graph.naming import P21_NS, default_graph_iri, derived_graph_iri, instance_prefix
from stepnc_graph.query import QueryResult, query
from stepnc_graph.store import GraphStore, default_store_path

__all__ = ["GraphInfo", "LoadResult", "QueryResult", "export", "graph_iri_for", "info", "load", "open_store", "query",
           "unload"]


def open_store(path: str | Path | None = None, memory: bool = False) -> GraphStore:
    """The on-disk store at ``path`` (default: ``$STEPNC_GRAPH_STORE`` or ``./.stepnc-graph``), or an in-memory one."""
    return GraphStore(None if memory else (path or default_store_path()))


def graph_iri_for(path: str | Path, base_iri: str | None, several: bool) -> str:
    """The graph IRI of a file: ``base_iri`` itself for one file; with several files it
    is a prefix to which each file name is added; by default derived from the name."""
    if base_iri is None:
        return default_graph_iri(str(path))
    if several:
        return instance_prefix(base_iri) + Path(path).name
    return base_iri


def load(store: GraphStore, paths: Iterable[str | Path], *, lenient: bool = False, base_iri: str | None = None,
         progress: Progress | None = None) -> list[LoadResult]:
    """Load each file into its own named graph (replacing an earlier load of it).

    A file that does not parse in strict mode raises Part21SyntaxError; files
    before it stay loaded, the store is unchanged for that file.
    """
    files = list(paths)
    return [load_file(store, p, lenient=lenient, base_iri=graph_iri_for(p, base_iri, len(files) > 1),
                      progress=progress) for p in files]


def unload(store: GraphStore, graph: str) -> bool:
    """Remove a file's graph and its derived layer; False if there was none."""
    return store.remove_graph(graph, companions=(derived_graph_iri(graph),))


@dataclass(frozen=True)
class GraphInfo:
    graph: str
    source: str | None
    triples: int
    instances: int | None
    raw_instances: int | None
    diagnostics: int | None
    loaded: str | None

    def asdict(self) -> dict[str, Any]:
        return asdict(self)


def _int(value: str | None) -> int | None:
    return int(value) if value is not None else None


def info(store: GraphStore) -> list[GraphInfo]:
    """The graphs in the store with what their load recorded."""
    out = []
    for g in store.graphs():
        rows = list(store.query(
            f"PREFIX p21: <{P21_NS}> PREFIX dcterms: <http://purl.org/dc/terms/> "
            f"PREFIX prov: <http://www.w3.org/ns/prov#> SELECT ?src ?n ?raw ?d ?t WHERE {{ GRAPH <{g}> {{ "
            f"OPTIONAL {{ <{g}> dcterms:source ?src }} OPTIONAL {{ <{g}> p21:instanceCount ?n }} "
            f"OPTIONAL {{ <{g}> p21:rawInstanceCount ?raw }} OPTIONAL {{ <{g}> p21:diagnosticCount ?d }} "
            f"OPTIONAL {{ <{g}> prov:generatedAtTime ?t }} }} }} LIMIT 1"))
        values = {k: (t.value if t is not None else None) for k, t in
                  zip(("src", "n", "raw", "d", "t"), rows[0], strict=True)} if rows else {}
        out.append(GraphInfo(g, values.get("src"), store.count(g), _int(values.get("n")), _int(values.get("raw")),
                             _int(values.get("d")), values.get("t")))
    return out
