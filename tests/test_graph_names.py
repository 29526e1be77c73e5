"""Graph names a program reserves (naming.GraphLayout): no load, unload or link takes the place of
another program, its derived layer or its link graphs, the vocabulary graph or a staging graph --
on a store in memory, on disk and behind a SPARQL endpoint alike."""

from __future__ import annotations

import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

import stepnc_graph as sg
from stepnc_graph.core.naming import (
    P21_NS,
    STAGING,
    VOCABULARY_GRAPH,
    GraphLayout,
    GraphNameError,
    derived_graph_iri,
    link_graph_iri,
)
from stepnc_graph.store.remote import open_remote
from stepnc_graph.store import GraphStore, Store
from stepnc_graph.core.naming import listed_graphs

from conftest import ROOT
from oxigraph_server import OxigraphServer, ServerUnavailable

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
MAPPING = ROOT / "examples" / "shaft_plm_links.csv"
CLI = [sys.executable, "-m", "stepnc_graph.cli"]
DCT = "http://purl.org/dc/terms/"
A = "http://x.example/a"


@pytest.fixture(params=["memory", "disk", "remote"])
def store(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Store]:
    """A store of each kind: in memory, on disk, and a real Oxigraph server over the protocols."""
    if request.param == "memory":
        yield sg.open_store(memory=True)
    elif request.param == "disk":
        with sg.open_store(tmp_path / "store") as disk:
            yield disk
    else:
        server = OxigraphServer(tmp_path / "server-data")
        try:
            server.start()
        except ServerUnavailable as exc:
            pytest.skip(str(exc))
        try:
            with open_remote(server.url) as remote:
                yield remote
        finally:
            server.stop()


def snapshot(store: Store) -> dict[str, int]:
    """Every named graph of the store with its quads."""
    return {g: store.count(g) for g in store.all_graphs()}


def record_program(store: Store, graph: str) -> None:
    """A graph that records itself as a program, written past the name checks (as an older
    stepnc-graph, or any SPARQL client, could)."""
    store.update(f"INSERT DATA {{ GRAPH <{graph}> {{ <{graph}> a <{P21_NS}ExchangeStructure> ; "
                 f"<{DCT}source> \"elsewhere.stp\" }} }}")


def add_link(store: Store, program: str) -> str:
    """A link graph of ``program``: by `link` where it runs (a store of this process), else written
    as `link` writes its records."""
    if isinstance(store, GraphStore):
        return sg.link(store, MAPPING, program).link_graph
    target = link_graph_iri(program, MAPPING.name)
    store.update(f"INSERT DATA {{ GRAPH <{target}> {{ <{target}> a <{P21_NS}LinkGraph> ; <{P21_NS}linkedProgram> "
                 f"<{program}> . <{program}/i1> <{DCT}identifier> \"PN 1\" }} }}")
    return target


# -- the rules, on their own ---------------------------------------------------------------------------


@pytest.mark.parametrize(("first", "second", "clash"), [
    (A, A + "/derived", True),                   # the other's derived layer
    (A, A + "/derived/step1", True),             # under it
    (A, A + "/links/m.csv", True),               # a link graph's name
    (A, A + "/", True),                          # both derived layers would be A/derived
    (A + "#", A + "#links/x", True),
    (A, A + "/links", True),                     # A/links/derived: its derived layer, and a link graph's name of A
    (A, A + "/linksx", False),
    (A, A + "/i12", False),                      # an instance's IRI names no graph of A
    (A, A + "#derived", False),
    (A, "http://x.example/ab", False),
])
def test_two_programs_share_no_name(first: str, second: str, clash: bool) -> None:
    empty = GraphLayout(frozenset(), frozenset())
    one = GraphLayout(frozenset({first, derived_graph_iri(first)}), frozenset({first}))
    for refuse in (lambda: one.refuse_program(second), lambda: empty.refuse_programs([first, second]),
                   lambda: GraphLayout(frozenset({second}), frozenset({second})).refuse_program(first)):
        if clash:
            with pytest.raises(GraphNameError) as caught:
                refuse()
            assert f"<{first}>" in str(caught.value) and f"<{second}>" in str(caught.value)
        else:
            refuse()


# -- load --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("first", "second"), [
    (A + "/derived", A), (A, A + "/derived"),
    (A + "/links/m.csv", A), (A, A + "/links/m.csv"),
    (A, A + "/"), (A + "/derived/step1", A),
])
def test_a_load_never_takes_another_programs_names(store: Store, first: str, second: str) -> None:
    sg.load(store, [EXAMPLE], base_iri=first)
    before, p21 = snapshot(store), sg.export(store, "p21", first)
    with pytest.raises(GraphNameError) as caught:
        sg.load(store, [EXAMPLE], base_iri=second, replace=True)  # --replace does not make it right
    assert f"<{first}>" in str(caught.value) and f"<{second}>" in str(caught.value)
    assert snapshot(store) == before and sg.export(store, "p21", first) == p21
    assert [g.graph for g in sg.info(store)] == [first]


@pytest.mark.parametrize("name", [VOCABULARY_GRAPH, f"{STAGING}1:{'0' * 32}", STAGING + "x"])
def test_reserved_names_are_refused(store: Store, name: str) -> None:
    sg.load(store, [EXAMPLE], base_iri=A)
    before = snapshot(store)
    with pytest.raises(GraphNameError, match="reserved|vocabulary"):
        sg.load(store, [EXAMPLE], base_iri=name)
    assert snapshot(store) == before


def test_a_program_may_be_named_like_the_layer_of_a_graph_that_is_no_program(store: Store) -> None:
    """Names are judged by what the store records, not by their shape: ``U/derived`` is a program's
    own name when ``U`` is a graph a user wrote, and it is listed as one."""
    store.update(f"INSERT DATA {{ GRAPH <{A}> {{ <urn:x> <urn:p> \"a note\" }} }}")
    [result] = sg.load(store, [EXAMPLE], base_iri=A + "/derived")
    assert result.graph in listed_graphs(store) and A in listed_graphs(store)


def test_the_cli_refuses_with_exit_2_naming_both_graphs(tmp_path: Path) -> None:
    db = str(tmp_path / "store")
    run = [*CLI, "load", "--store", db]
    assert subprocess.run([*run, "--base-iri", A + "/derived", str(EXAMPLE)], capture_output=True).returncode == 0
    done = subprocess.run([*run, "--base-iri", A, str(EXAMPLE)], capture_output=True, text=True)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert f"<{A}>" in done.stderr and f"<{A}/derived>" in done.stderr
    with sg.open_store(db, readonly=True) as s:
        assert [g.graph for g in sg.info(s)] == [A + "/derived"] and s.count(A + "/derived") > 700


# -- unload ------------------------------------------------------------------------------------------------


def test_unload_removes_what_the_store_records_as_the_programs(store: Store) -> None:
    """A program goes with its derived layer and the link graphs that record it as theirs; a
    program or a user graph that only looks like one of its link graphs stays, whole, and so does
    a graph that claims to be one outside the program's names."""
    sg.load(store, [EXAMPLE], base_iri=A)
    link = add_link(store, A)
    other = A + "/links/other.stp"  # a program an older stepnc-graph let be loaded there
    sg.load(store, [EXAMPLE], base_iri="http://x.example/elsewhere")
    store.update(f"COPY <http://x.example/elsewhere> TO <{other}>")
    record_program(store, other)
    note = A + "/links/notes"
    store.update(f"INSERT DATA {{ GRAPH <{note}> {{ <urn:x> <urn:p> \"a user's graph\" }} }}")
    claims = "urn:x:claims-to-link-a"  # not where `link` names a link graph of A
    store.update(f"INSERT DATA {{ GRAPH <{claims}> {{ <{claims}> a <{P21_NS}LinkGraph> ; "
                 f"<{P21_NS}linkedProgram> <{A}> }} }}")
    kept = {g: n for g, n in snapshot(store).items() if g in (other, note, claims)}
    assert sg.unload(store, A)
    after = snapshot(store)
    assert not {A, A + "/derived", link} & set(after)
    assert {g: after.get(g) for g in kept} == kept


@pytest.mark.parametrize("what", ["vocabulary", "derived layer", "staging"])
def test_unload_refuses_what_is_not_a_program_or_a_link_graph(store: Store, what: str) -> None:
    [r] = sg.load(store, [EXAMPLE], base_iri=A)
    name = {"vocabulary": VOCABULARY_GRAPH, "derived layer": derived_graph_iri(r.graph),
            "staging": f"{STAGING}1:{'0' * 32}"}[what]
    before = snapshot(store)
    with pytest.raises(GraphNameError) as caught:
        sg.unload(store, name)
    assert f"<{name}>" in str(caught.value)
    if what == "derived layer":
        assert f"unload <{A}>" in str(caught.value)
    assert snapshot(store) == before


def test_unload_of_a_link_graph_removes_it_alone(store: Store) -> None:
    sg.load(store, [EXAMPLE], base_iri=A)
    link = add_link(store, A)
    before = snapshot(store)
    assert sg.unload(store, link)
    assert snapshot(store) == {g: n for g, n in before.items() if g != link}


def test_the_cli_unload_refuses_each_and_removes_the_others(tmp_path: Path) -> None:
    db = str(tmp_path / "store")
    subprocess.run([*CLI, "load", "--store", db, "--base-iri", A, str(EXAMPLE)], check=True, capture_output=True)
    subprocess.run([*CLI, "load", "--store", db, "--base-iri", A + "x", str(EXAMPLE)], check=True, capture_output=True)
    done = subprocess.run([*CLI, "unload", "--store", db, VOCABULARY_GRAPH, A + "/derived", A + "x"],
                          capture_output=True, text=True)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert f"removed: {A}x" in done.stdout and "vocabulary graph" in done.stderr and f"unload <{A}>" in done.stderr
    with sg.open_store(db, readonly=True) as s:
        assert listed_graphs(s) == [A] and s.has_graph(A + "/derived") and s.count(VOCABULARY_GRAPH) > 0


# -- link ---------------------------------------------------------------------------------------------------


@pytest.fixture(params=["memory", "disk"])
def local(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[GraphStore]:
    """`link` writes into a store of this process."""
    with sg.open_store(tmp_path / "store", memory=request.param == "memory") as s:
        yield s


def test_link_attaches_to_programs_only(local: GraphStore) -> None:
    sg.load(local, [EXAMPLE], base_iri=A)
    before = snapshot(local)
    with pytest.raises(GraphNameError, match=f"<{A}/derived> is not a program graph"):
        sg.link(local, MAPPING, A + "/derived")
    assert snapshot(local) == before


def test_link_never_replaces_a_graph_that_is_not_its_own(local: GraphStore) -> None:
    sg.load(local, [EXAMPLE], base_iri=A)
    target = link_graph_iri(A, MAPPING.name)
    local.update(f"INSERT DATA {{ GRAPH <{target}> {{ <urn:x> <urn:p> \"a user's graph\" }} }}")
    before = snapshot(local)
    with pytest.raises(GraphNameError) as caught:
        sg.link(local, MAPPING, A, replace=True)
    assert f"<{target}>" in str(caught.value) and f"<{A}>" in str(caught.value)
    assert snapshot(local) == before
    local.update(f"DROP GRAPH <{target}>")
    assert sg.link(local, MAPPING, A).link_graph == target  # once the name is free
    assert sg.link(local, MAPPING, A).link_graph == target  # and again: it is its own now


# -- staging graphs of a remote store ---------------------------------------------------------------------


def test_an_old_program_under_a_staging_name_survives_the_next_remote_load(tmp_path: Path) -> None:
    """A remote load drops the staging graphs interrupted loads left, once stale: never a graph
    that records itself as a program (an older stepnc-graph let one be loaded under such a name)."""
    server = OxigraphServer(tmp_path / "server-data")
    try:
        server.start()
    except ServerUnavailable as exc:
        pytest.skip(str(exc))
    try:
        with open_remote(server.url) as remote:
            stale = f"{int(time.time()) - 7 * 86400}:{uuid.uuid4().hex}"
            program, left = STAGING + stale, f"{STAGING}{int(time.time()) - 7 * 86400}:{uuid.uuid4().hex}"
            record_program(remote, program)
            remote.update(f"INSERT DATA {{ GRAPH <{left}> {{ <urn:x> <urn:p> \"left by a load\" }} }}")
            sg.load(remote, [EXAMPLE], base_iri=A)
            assert remote.count(program) == 2 and not remote.has_graph(left)
    finally:
        server.stop()

