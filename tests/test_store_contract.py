"""The store contract (:mod:`stepnc_graph.store.contract`): every store back end -- in memory, on
disk, a remote SPARQL endpoint (Oxigraph's server, started as tests/test_remote.py starts it) --
passes the same checks, and answers what its declared capabilities say. A new back end joins the
``backend`` fixture's parameters."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pyoxigraph as ox
import pytest

import stepnc_graph as sg
from stepnc_graph.core.naming import STAGING, VOCABULARY_GRAPH, GraphNameError, derived_graph_iri
from stepnc_graph.store import StoreError
from stepnc_graph.store.contract import Capabilities, Companion, Maintenance, Store, is_store, members
from stepnc_graph.store.remote import open_remote

from oxigraph_server import OxigraphServer
from test_remote import server  # noqa: F401 -- the fixture that starts Oxigraph's server

G = "urn:contract:g"
LAYER = derived_graph_iri(G)
TRIPLE = "<urn:s> <urn:p> <urn:o> .\n"
TWO = TRIPLE + "<urn:s> <urn:p> \"two\" .\n"

Opener = Callable[[], Store]


@pytest.fixture(params=["memory", "disk", "remote"])
def backend(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[str, Opener]]:
    """(kind, open): ``open()`` opens the store anew (the same data for a persistent one)."""
    kind = request.param
    if kind == "memory":
        memory = sg.open_store(memory=True)
        yield kind, lambda: memory
    elif kind == "disk":
        yield kind, lambda: sg.open_store(tmp_path / "store")
    else:
        srv: OxigraphServer = request.getfixturevalue("server")
        yield kind, lambda: open_remote(srv.url)


@pytest.fixture
def store(backend: tuple[str, Opener]) -> Iterator[Store]:
    with backend[1]() as opened:
        yield opened


def _ntriples(store: Store, graph: str) -> set[str]:
    return {f"{q.subject} {q.predicate} {q.object} .\n" for q in store.quads(graph)}


def test_every_back_end_implements_the_whole_protocol(store: Store) -> None:
    assert is_store(store) and not is_store([Path("a.stp")])
    missing = [name for name in members() if not hasattr(type(store), name) and name not in vars(store)]
    assert not missing and {"replace_graph", "capabilities", "maintenance", "last_removal"} <= set(members())
    assert isinstance(store.capabilities, Capabilities)
    assert isinstance(store.location, str) and store.location


def test_where_it_is(backend: tuple[str, Opener], store: Store, tmp_path: Path) -> None:
    kind = backend[0]
    expected = {"memory": "memory", "disk": str((tmp_path / "store").resolve())}
    if kind in expected:
        assert store.location == expected[kind]
    else:
        assert store.location.startswith("http://127.0.0.1:")


def test_replace_writes_exactly_the_chunks_and_companions(store: Store) -> None:
    store.replace_graph(G, [TWO, Companion(LAYER, TRIPLE)], companions=(LAYER,))
    assert _ntriples(store, G) == set(TWO.splitlines(True)) and store.count(G) == 2
    assert store.count(LAYER) == 1 and store.has_graph(G) and store.has_graph(LAYER)
    assert {G, LAYER} <= set(store.all_graphs()) and store.all_graphs() == sorted(store.all_graphs())
    store.replace_graph(G, [TRIPLE], companions=(LAYER,))
    assert _ntriples(store, G) == {TRIPLE} and not store.has_graph(LAYER)
    assert bool(store.query(f"ASK {{ GRAPH <{G}> {{ <urn:s> <urn:p> <urn:o> }} }}"))


def test_before_commit_writes_into_the_load_and_a_failure_rolls_back(store: Store) -> None:
    def complete(target: Callable[[str], str]) -> None:
        store.add_ntriples(target(G), "<urn:s> <urn:q> <urn:r> .\n")
        store.add_turtle(target(LAYER), "<urn:a> <urn:b> 1 .")
        store.update(f"INSERT DATA {{ GRAPH <{target(LAYER)}> {{ <urn:a> <urn:b> 2 }} }}")

    store.replace_graph(G, [TRIPLE], complete, companions=(LAYER,))
    assert store.count(G) == 2 and store.count(LAYER) == 2

    def fail(target: Callable[[str], str]) -> None:
        store.add_ntriples(target(G), "<urn:s> <urn:q> <urn:lost> .\n")
        raise RuntimeError("stop")

    with pytest.raises(RuntimeError, match="stop"):
        store.replace_graph(G, [TWO], fail, companions=(LAYER,))
    assert store.count(G) == 2 and store.count(LAYER) == 2  # as it was
    assert not any(g.startswith(STAGING) for g in store.all_graphs())


def test_remove_takes_the_companions_and_says_whether_there_was_a_graph(store: Store) -> None:
    store.replace_graph(G, [TRIPLE, Companion(LAYER, TRIPLE)], companions=(LAYER,))
    assert store.remove_graph(G, companions=(LAYER,)) is True
    assert not store.has_graph(G) and not store.has_graph(LAYER) and store.count(G) == 0
    assert store.remove_graph(G) is False


def test_reserved_names_and_strangers_are_refused(store: Store) -> None:
    with pytest.raises(GraphNameError):
        store.replace_graph(VOCABULARY_GRAPH, [TRIPLE])
    with pytest.raises(GraphNameError):
        store.replace_graph(G, [TRIPLE], companions=("urn:other",))
    with pytest.raises(GraphNameError):
        store.remove_graph(G, companions=("urn:other",))
    assert not store.has_graph(G)


def test_quads_for_pattern_matches_like_oxigraph(store: Store) -> None:
    store.replace_graph(G, [TWO])
    found = list(store.quads_for_pattern(ox.NamedNode("urn:s"), None, ox.Literal("two"), ox.NamedNode(G)))
    assert found == [ox.Quad(ox.NamedNode("urn:s"), ox.NamedNode("urn:p"), ox.Literal("two"), ox.NamedNode(G))]
    assert {q.object for q in store.quads_for_pattern(None, ox.NamedNode("urn:p"), None)} == \
        {ox.NamedNode("urn:o"), ox.Literal("two")}


def test_a_local_copy_holds_the_graphs_and_reads_locally(store: Store) -> None:
    store.replace_graph(G, [TWO])
    store.replace_graph("urn:contract:h", [TRIPLE])
    with store.local_copy(G) as copy:
        assert copy.capabilities.local_reads and not copy.capabilities.persistent
        assert copy.all_graphs() == [G] and _ntriples(copy, G) == _ntriples(store, G)
    with store.local_copy() as copy:
        assert set(copy.all_graphs()) == set(store.all_graphs())
    assert store.count(G) == 2  # the store is untouched by its copy's closing


def test_a_persistent_store_keeps_its_graphs(backend: tuple[str, Opener]) -> None:
    kind, open_ = backend
    with open_() as store:
        store.replace_graph(G, [TWO])
        persistent = store.capabilities.persistent
    assert persistent == (kind != "memory")
    if persistent:
        with open_() as again:
            assert _ntriples(again, G) == set(TWO.splitlines(True))


def test_blank_node_writes_as_declared(store: Store) -> None:
    node = ox.BlankNode()
    graph = ox.NamedNode(G)
    quads = [ox.Quad(ox.NamedNode("urn:s"), ox.NamedNode("urn:p"), node, graph),
             ox.Quad(node, ox.NamedNode("urn:q"), ox.Literal("cell"), graph)]
    if not store.capabilities.blank_node_writes:
        with pytest.raises(StoreError):
            store.add_quads(quads)
        return
    assert store.add_quads(quads) == 2
    [row] = list(store.query(f"SELECT ?v WHERE {{ GRAPH <{G}> {{ <urn:s> <urn:p> ?b . ?b <urn:q> ?v }} }}"))
    assert row[0] == ox.Literal("cell")  # the two quads still share their node


def test_local_reads_as_declared(store: Store) -> None:
    if store.capabilities.local_reads:
        assert isinstance(store.oxigraph, ox.Store)
    else:
        with pytest.raises(StoreError):
            store.oxigraph  # noqa: B018 -- the property is what is tested


def test_maintenance_and_compaction_as_declared(store: Store) -> None:
    store.replace_graph(G, [TWO])
    state = store.maintenance()
    if state is None:  # the back end manages its own storage
        assert not store.capabilities.compactable
        with pytest.raises(StoreError):
            store.compact()
        return
    assert isinstance(state, Maintenance) and state.deleted_quads >= 0
    assert (state.disk_bytes > 0) == store.capabilities.persistent
    store.remove_graph(G)
    store.compact()
    after = store.maintenance()
    assert after is not None and after.deleted_quads == 0 and not store.has_graph(G)
    if store.capabilities.compactable:
        assert after.disk_bytes > 0
