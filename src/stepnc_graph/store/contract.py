"""The store contract: what every store back end offers and what it declares it can do.

Callers (loading, export, queries, validation, the CLI) hold a :class:`Store` and ask its
:class:`Capabilities` where back ends differ; they never test which back end they have. A
new back end implements this protocol and passes ``tests/test_store_contract.py``, which runs
the same checks against every store (in memory, on disk, a remote SPARQL endpoint).

The store knows named graphs and quads, not programs: which graphs are programs, link graphs or
derived layers is read from the graphs' own records by :mod:`stepnc_graph.core.naming`
(:func:`~stepnc_graph.core.naming.graph_layout`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, TypeGuard

import pyoxigraph as ox


@dataclass(frozen=True)
class Capabilities:
    """What a back end can do, declared by it (in the manner of rdflib's ``Store`` flags).

    ``persistent``: its data outlives the process (a directory, an endpoint): a load writes the
    vocabulary graph into it, and a check reading ``$shapesGraph`` is not run in place on it.
    ``blank_node_writes``: :meth:`Store.add_quads` keeps the blank nodes it is given (an
    embedded database); elsewhere blank nodes cannot be named across requests, so a writer
    copies them with SPARQL Update inside the store. ``local_reads``: reading node by node
    (:meth:`Store.quads_for_pattern`, :attr:`Store.oxigraph`) is cheap; elsewhere the graphs
    are copied first (:meth:`Store.local_copy`). ``compactable``: :meth:`Store.compact` gives
    disk space back. ``ordered_group_concat``: a ``GROUP_CONCAT`` lists its values in the order
    they reach it (an ordered sub-SELECT's order): SPARQL 1.1 (section 18.5.1.7) leaves that order
    to the store; Oxigraph keeps it, Virtuoso 7 does not, so a query result whose lists differ
    is named to the user (:func:`stepnc_graph.querying.query.run`), not passed on silently.
    ``plans_joins``: the store finds a good join order for a request by itself; one that does not
    (Virtuoso 7 on some data) gets the operations that join a ``VALUES`` block with a graph written
    block first, after ``join_order_prologue``, its own words for "join in the order written".
    ``blank_node_iri_prefix``: a blank node's label in the store's answers that begins so, written
    as an IRI, names that node in a later request (Virtuoso: ``nodeID://``); '' for none.
    """

    persistent: bool
    blank_node_writes: bool
    local_reads: bool
    compactable: bool
    ordered_group_concat: bool = True
    plans_joins: bool = True
    join_order_prologue: str = ""
    blank_node_iri_prefix: str = ""


@dataclass(frozen=True)
class Maintenance:
    """The storage state of a store that manages its own files (see :meth:`Store.maintenance`):
    quads deleted since the last compaction (their space comes back then) and bytes on disk."""

    deleted_quads: int
    disk_bytes: int


@dataclass(frozen=True)
class Companion:
    """Text for a companion graph of a load (its derived layer), met among the load's chunks.

    A companion chunk is loaded where its graph is written now (a staging graph
    during an in-memory or remote replacement), so a loader can write the
    companion while it streams the main graph instead of keeping it for later.
    """

    graph: str
    text: str


@dataclass(frozen=True)
class Joint:
    """Text of the main graph (``text``) with lines of its companion ``graph`` (``lines``) that
    name the text's blank nodes -- the derived layer's list positions on the program's list
    cells, its generic values that are lists or typed values -- met among the load's chunks.

    A blank node's label holds inside one document only (Oxigraph names a document's blank
    nodes anew), so a store that writes blank nodes (:attr:`Capabilities.blank_node_writes`)
    loads both parts as one document, the lines into the companion's graph. One that cannot
    (a remote endpoint) loads ``text`` alone, and the load copies those facts inside the store
    (:func:`stepnc_graph.loading.derive.derive`). Either way a replacement compares the lines,
    named as in the main text, against the version in the store (see :mod:`stepnc_graph.store`).
    """

    text: str
    graph: str
    lines: str


Chunk = str | Companion | Joint


class Store(Protocol):
    """Every member a caller may use of a store (:class:`~stepnc_graph.store.GraphStore` in
    memory or on disk, :class:`~stepnc_graph.store.remote.RemoteStore`)."""

    #: how the last graph removal was done ("delete", "rebuild", "difference", ...; None: none yet)
    last_removal: str | None

    @property
    def capabilities(self) -> Capabilities: ...

    @property
    def location(self) -> str:
        """Where the store is, for users: its absolute directory, its endpoint, or "memory"."""
        ...

    @property
    def server(self) -> str | None:
        """The software answering for the store as it names itself (an endpoint's HTTP ``Server``
        header, once it has answered), for messages about what it does otherwise; None when
        embedded or unknown."""
        ...

    def maintenance(self) -> Maintenance | None:
        """The storage state, or None when the back end manages its own storage (an endpoint)."""
        ...

    # -- writing --------------------------------------------------------------------------

    def prepare_to_write(self) -> None:
        """Make ready for a write that reads the store first: an on-disk store opened lazily takes
        the writer's lock now (:class:`~stepnc_graph.store.StoreBusy` if another process writes) and
        reads the newest published state; elsewhere nothing to do. The API's writers call it first."""
        ...

    def replace_graph(self, graph: str, chunks: Iterable[Chunk],
                      before_commit: Callable[[Callable[[str], str]], None] | None = None,
                      companions: Sequence[str] = ()) -> None:
        """Atomically make ``graph`` hold exactly the N-Triples in ``chunks`` (and ``companions``
        what :class:`Companion` chunks and ``before_commit`` write); an exception rolls back."""
        ...

    def remove_graph(self, graph: str, companions: Sequence[str] = (), compact: bool = False) -> bool: ...

    def add_ntriples(self, graph: str, text: str, bulk: bool = False) -> None: ...

    def add_turtle(self, graph: str, text: str) -> None: ...

    def add_quads(self, quads: Iterable[ox.Quad]) -> int:
        """Add quads, blank nodes as given (only where ``capabilities.blank_node_writes``)."""
        ...

    def update(self, sparql: str) -> None: ...

    def compact(self, progress: Callable[[int, int], None] | None = None) -> None:
        """Give disk space back (where ``capabilities.compactable``; a no-op in memory)."""
        ...

    # -- reading --------------------------------------------------------------------------

    def all_graphs(self) -> list[str]:
        """Every named graph but staging ones, sorted."""
        ...

    def has_graph(self, graph: str) -> bool: ...

    def query(self, sparql: str, **kwargs: Any) -> Any: ...

    def count(self, graph: str | None = None) -> int: ...

    def quads(self, graph: str | None = None) -> Iterator[ox.Quad]: ...

    def quads_for_pattern(self, subject: Any, predicate: Any, obj: Any, graph: Any = None) -> Iterator[ox.Quad]: ...

    def kept_text(self, graph: str, path: Path, store_labels: bool = True) -> bool:
        """Write ``graph`` to ``path`` as N-Triples from what the store kept of its last load, where
        that is cheaper than reading the graph and still describes it (``store_labels=False``: blank
        nodes labelled as the load wrote them, for a text of that graph alone); False, and nothing
        to use, elsewhere."""
        ...

    def local_copy(self, graphs: str | Sequence[str] | None = None) -> Any:
        """An in-memory store holding ``graphs`` (one, several, every one), for work that reads
        node by node; the caller closes it."""
        ...

    @property
    def oxigraph(self) -> ox.Store:
        """The embedded database (where ``capabilities.local_reads``; else StoreError)."""
        ...

    def close(self) -> None: ...

    def __enter__(self) -> Any: ...

    def __exit__(self, *exc: object) -> None: ...


def members() -> list[str]:
    """The names :class:`Store` declares (for the contract test: every back end has each)."""
    declared = {n for n in vars(Store) if not n.startswith("_") or n in ("__enter__", "__exit__")}
    return sorted(declared | set(Store.__annotations__))


def is_store(value: object) -> TypeGuard[Store]:
    """Whether ``value`` is a store (it declares :class:`Capabilities`), not, say, a list of files.
    Asked of its class, so that no property of the store runs."""
    return isinstance(getattr(type(value), "capabilities", None), Capabilities | property)
