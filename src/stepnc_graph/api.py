"""The Python API: the same operations as the command line.

    import stepnc_graph as sg
    store = sg.open_store(memory=True)
    [result] = sg.load(store, ["part.stp"], lenient=True)
    print(result.instances, result.triples, result.diagnostics)
    turtle = sg.export(store, "ttl", result.graph)
    rows = sg.query(store, "tool-changes").rows     # a library query; keyword arguments are parameters
    report = sg.validate(["part.stp"])               # SHACL: the ISO 14649 shapes and process rules
    report = sg.validate(["data.ttl"], extra_shapes=["shapes.ttl"], iso_shapes=False)  # any RDF, any shapes
    plan = sg.build_plan(store)                      # the workplan: tool changes, a networkx graph, a picture
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass
from pathlib import Path
from importlib import import_module
from typing import TYPE_CHECKING, Any

from stepnc_graph.loading.common import LoadResult, Progress, SourceError
from stepnc_graph.loading.loader import load_paths
from stepnc_graph.core.naming import P21_NS, GraphNameError
from stepnc_graph.core.naming import graph_layout, program_graphs
from stepnc_graph.store import GraphStore, Store, StoreBusy, StoreError, open_store

if TYPE_CHECKING:
    from stepnc_graph.exporting.exporter import export
    from stepnc_graph.loading.link import LinkResult, link
    from stepnc_graph.querying.query import QueryResult, query
    from stepnc_graph.validation import validate
    from stepnc_graph.workplan.plan import Plan, build_plan

#: API names whose modules are imported on first use: `load` (the commonest command) does not
#: pay for the exporters, the SHACL engine or the link and query layers.
_LAZY = {"export": "stepnc_graph.exporting.exporter", "link": "stepnc_graph.loading.link", "LinkResult": "stepnc_graph.loading.link",
         "query": "stepnc_graph.querying.query", "QueryResult": "stepnc_graph.querying.query", "validate": "stepnc_graph.validation",
         "build_plan": "stepnc_graph.workplan.plan", "Plan": "stepnc_graph.workplan.plan"}

__all__ = ["Compacted", "GraphInfo", "GraphNameError", "GraphStore", "LinkResult", "LoadResult", "Plan", "QueryResult",
           "SourceError", "StoreBusy", "StoreError", "build_plan", "compact", "export", "info", "link", "load", "open_store",
           "query", "unload", "validate"]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def load(store: Store, paths: Iterable[str | Path], *, lenient: bool = False, base_iri: str | None = None,
         progress: Progress | None = None, replace: bool = False, derived: bool = True,
         positions: bool = True, edition: str | None = None) -> list[LoadResult]:
    """Load each file (a directory: every Part 21 file under it; ``-``: standard input)
    into its own named graph, replacing an earlier load of the same file.

    Graph IRIs are planned first (:func:`stepnc_graph.loading.sources.plan_sources`):
    two inputs that would share a graph, or a graph already holding another
    file (unless ``replace``), raise :class:`~stepnc_graph.loading.sources.SourceError`
    before anything is written. A file that does not parse in strict mode raises
    Part21SyntaxError; files before it stay loaded, the store is unchanged for it.
    ``derived=False`` leaves out the derived query layer (:mod:`stepnc_graph.loading.derive`):
    for a throw-away store that only :func:`validate` reads; so is ``positions=False``
    (Part 21 files: no ``p21:id``/``p21:line`` triples, the lines in ``LoadResult.lines``).
    ``edition`` reads every Part 21 file in that edition of ISO 14649 (default: each file's own,
    :func:`stepnc_graph.mapping.editions.decide_edition`).
    """
    return load_paths(store, paths, lenient=lenient, base_iri=base_iri, progress=progress, replace=replace,
                      derived=derived, positions=positions, edition=edition)


def unload(store: Store, graph: str, compact: bool = False) -> bool:
    """Remove a program's graph with its derived layer and its link graphs (:mod:`stepnc_graph.loading.link`),
    or a link graph alone, atomically; False if there was none. Which graphs are the program's
    comes from the store's records (:meth:`~stepnc_graph.core.naming.GraphLayout.unloaded_with`), so
    another program is never removed with it; the vocabulary graph and a derived layer on its
    own raise :class:`~stepnc_graph.core.naming.GraphNameError`. Beside other programs the store
    compacts once enough was deleted (:data:`~stepnc_graph.store.tuning.COMPACT_AT`); ``compact`` gives
    the space back now."""
    store.prepare_to_write()  # the graphs that go with it, read from the newest published state
    companions = graph_layout(store).unloaded_with(graph)
    return store.remove_graph(graph, companions=companions, compact=compact)


@dataclass(frozen=True)
class Compacted:
    """What :func:`compact` did: the store's bytes on disk before and after, and the quads it holds."""

    before: int
    after: int
    quads: int

    def asdict(self) -> dict[str, Any]:
        return asdict(self)


def compact(store: Store, progress: Callable[[int, int], None] | None = None) -> Compacted:
    """Rebuild an on-disk store's database from its graphs, atomically, giving back the space
    that removed programs still hold (:meth:`GraphStore.compact` says why an unload alone does
    not). ``progress(done, total)`` counts the quads copied. A SPARQL endpoint manages its own
    storage: :class:`StoreError`."""
    store.prepare_to_write()
    before = store.maintenance()
    if before is None:
        raise StoreError("compact works on a stepnc-graph store directory; a SPARQL endpoint manages its own storage")
    store.compact(progress)
    after = store.maintenance()
    return Compacted(before.disk_bytes, after.disk_bytes if after else 0, store.count())


@dataclass(frozen=True)
class GraphInfo:
    graph: str
    source: str | None
    triples: int
    instances: int | None
    raw_instances: int | None
    diagnostics: int | None
    loaded: str | None
    #: the edition of ISO 14649 the file was read in, how that was chosen, and the evidence
    edition: str | None = None
    edition_chosen_by: str | None = None
    edition_evidence: tuple[str, ...] = ()

    def asdict(self) -> dict[str, Any]:
        return asdict(self)


def _int(value: str | None) -> int | None:
    return int(value) if value is not None else None


def info(store: Store) -> list[GraphInfo]:
    """The loaded files' graphs in the store with what their load recorded."""
    out = []
    for g in program_graphs(store):
        rows = list(store.query(
            f"PREFIX p21: <{P21_NS}> PREFIX dcterms: <http://purl.org/dc/terms/> "
            f"PREFIX prov: <http://www.w3.org/ns/prov#> SELECT ?src ?n ?raw ?d ?t WHERE {{ GRAPH <{g}> {{ "
            f"OPTIONAL {{ <{g}> dcterms:source ?src }} OPTIONAL {{ <{g}> p21:instanceCount ?n }} "
            f"OPTIONAL {{ <{g}> p21:rawInstanceCount ?raw }} OPTIONAL {{ <{g}> p21:diagnosticCount ?d }} "
            f"OPTIONAL {{ <{g}> prov:generatedAtTime ?t }} }} }} LIMIT 1"))
        values = {k: (t.value if t is not None else None) for k, t in
                  zip(("src", "n", "raw", "d", "t"), rows[0], strict=True)} if rows else {}
        edition = {str(r["p"].value).rsplit("#", 1)[1]: str(r["v"].value) for r in store.query(
            f"PREFIX p21: <{P21_NS}> SELECT ?p ?v WHERE {{ GRAPH <{g}> {{ <{g}> ?p ?v "
            f"VALUES ?p {{ p21:edition p21:editionChosenBy }} }} }}")}
        evidence = tuple(sorted(str(r["v"].value) for r in store.query(
            f"PREFIX p21: <{P21_NS}> SELECT ?v WHERE {{ GRAPH <{g}> {{ <{g}> p21:editionEvidence ?v }} }}")))
        out.append(GraphInfo(g, values.get("src"), store.count(g), _int(values.get("n")), _int(values.get("raw")),
                             _int(values.get("d")), values.get("t"), edition.get("edition"),
                             edition.get("editionChosenBy"), evidence))
    return out
