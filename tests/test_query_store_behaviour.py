"""The table of what particular stores do wrong (stepnc_graph.store.behaviour): each entry names
what it affects, and both readers -- the remote store's capabilities and the library's warnings --
follow it."""

from __future__ import annotations

import dataclasses

import pytest

from stepnc_graph.querying.query import known_wrong_answers, library
from stepnc_graph.store.behaviour import BEHAVIOURS, behaviours, lacks, wrong_answers
from stepnc_graph.store.contract import Capabilities
from stepnc_graph.store.remote import open_remote

from test_remote import empty_store, fake_endpoint

VIRTUOSO = "Virtuoso/07.20.3229 (Linux) x86_64-pc-linux-gnu"
SERVERS = [VIRTUOSO, "Oxigraph/0.5.2", "Apache-Coyote/1.1", None]


def test_every_behaviour_names_a_capability_or_library_queries_that_exist() -> None:
    capabilities = {f.name: f.default for f in dataclasses.fields(Capabilities)}
    names = {q.name for q in library()}
    for b in BEHAVIOURS:
        assert b.capability is not None or b.queries, b
        assert b.capability is None or capabilities.get(b.capability) is True, b  # a store has it unless named here
        assert b.queries <= names, b
        assert b.does and not b.does.endswith("."), b  # shown inside a sentence


def test_a_behaviour_applies_by_the_server_header_only() -> None:
    assert {b.does for b in behaviours(VIRTUOSO)} == {b.does for b in BEHAVIOURS}
    assert behaviours("  virtuoso/7.2") and not behaviours("Oxigraph/0.5.2") and not behaviours(None)
    assert not behaviours("MyProxy in front of Virtuoso/07.20")  # the header names the store first
    assert lacks(VIRTUOSO, "ordered_group_concat") and not lacks("Oxigraph/0.5.2", "ordered_group_concat")
    assert wrong_answers(VIRTUOSO, "operations-per-feature") and not wrong_answers(VIRTUOSO, "tool-changes")


@pytest.mark.parametrize("server", SERVERS)
def test_a_remote_stores_capabilities_follow_the_table(server: str | None) -> None:
    with fake_endpoint(empty_store, server) as (url, _), open_remote(url) as store:
        store.has_graph("urn:x")  # an answer: the store has named itself
        declared = dataclasses.asdict(store.capabilities)
        for b in BEHAVIOURS:
            if b.capability is not None:
                assert declared[b.capability] is not b.applies_to(server), (server, b)
        assert declared["ordered_group_concat"] is (server != VIRTUOSO)


@pytest.mark.parametrize("server", SERVERS)
def test_every_library_query_a_store_may_answer_wrongly_carries_the_reason(server: str | None) -> None:
    with fake_endpoint(empty_store, server) as (url, _), open_remote(url) as store:
        store.has_graph("urn:x")
        for q in library():
            said = known_wrong_answers(store, q.name)
            expected = wrong_answers(server, q.name)
            assert len(said) == len(expected), (server, q.name)
            for text, b in zip(said, expected, strict=True):
                assert text == f"{server} {b.does}"
        if server == VIRTUOSO:
            assert known_wrong_answers(store, "operations-per-feature")


@pytest.mark.parametrize("server", SERVERS)
def test_a_store_that_plans_joins_badly_is_given_its_words_for_joining_as_written(server: str | None) -> None:
    """Virtuoso 7.2 joined the derived layer's VALUES block of rules last on some data, by a nested
    loop over every quad (4.3-7.8 server CPU-s for a 10k-instance program's blank values); its
    ``DEFINE sql:select-option "order"`` joins as written. No other store is sent it."""
    from stepnc_graph.loading.derive import _blank_updates
    from stepnc_graph.loading.derive_rules import iso14649_rules

    with fake_endpoint(empty_store, server) as (url, _), open_remote(url) as store:
        store.has_graph("urn:x")
        capabilities = store.capabilities
    virtuoso = server == VIRTUOSO
    assert capabilities.plans_joins is not virtuoso
    assert capabilities.join_order_prologue == ('DEFINE sql:select-option "order"' if virtuoso else "")
    updates = _blank_updates(iso14649_rules(), "urn:x:staged", "urn:x:layer", capabilities.join_order_prologue)
    operations = updates.split(" ;\n")
    assert len(operations) == 2
    for operation in operations:
        assert operation.startswith(f"{capabilities.join_order_prologue}\nINSERT" if virtuoso else "INSERT")
        # the block of rules opens the pattern, so a store joining as written starts from it
        assert operation.split("WHERE", 1)[1].split("GRAPH <urn:x:staged> {", 1)[1].lstrip().startswith("VALUES")


@pytest.mark.parametrize("server", SERVERS)
def test_a_store_whose_labels_name_its_blank_nodes_is_written_list_positions_by_them(server: str | None) -> None:
    """Virtuoso's answers label a blank node ``nodeID://b10576``, and that IRI names the node in a
    later request: the client writes the list positions it counted by those IRIs (INSERT DATA,
    in pieces), exactly the embedded store's positions. A label of another form (no such store,
    or a node not from its answers) leaves the count to the store's own SPARQL."""
    import pyoxigraph as ox

    from stepnc_graph.loading.derive import _named_positions
    from stepnc_graph.loading.derive_order import Lists
    from stepnc_graph.store.answers import lenient_json_results, store_label

    with fake_endpoint(empty_store, server) as (url, _), open_remote(url) as store:
        store.has_graph("urn:x")
        prefix = store.capabilities.blank_node_iri_prefix
    assert prefix == ("nodeID://" if server == VIRTUOSO else "")
    answer = ('{"head": {"vars": ["c"]}, "results": {"bindings": [{"c": {"type": "bnode", "value": "nodeID://b%d"}}, '
              '{"c": {"type": "bnode", "value": "nodeID://b%d"}}, {"c": {"type": "bnode", "value": "nodeID://b%d"}}]}}')
    rdf = ox.NamedNode("http://www.w3.org/1999/02/22-rdf-syntax-ns#nil")
    cells = [row[0] for row in ox.parse_query_results(lenient_json_results((answer % (7, 8, 9)).encode(), False),
                                                     ox.QueryResultsFormat.JSON)]
    assert [store_label(c) for c in cells] == ["nodeID://b7", "nodeID://b8", "nodeID://b9"]
    members = [ox.NamedNode(f"urn:x:m{i}") for i in range(3)]
    lists = Lists(dict(zip(cells, members, strict=True)), {cells[0]: cells[1], cells[1]: cells[2], cells[2]: rdf})
    layer = ox.NamedNode("urn:x:layer")
    pieces = _named_positions(lists, layer, "nodeID://", piece=2)
    index = "<https://w3id.org/stepnc-graph/analysis#index>"
    integer = "^^<http://www.w3.org/2001/XMLSchema#integer>"
    assert pieces == [f'INSERT DATA {{ GRAPH <urn:x:layer> {{\n<nodeID://b7> {index} "1"{integer} .\n'
                      f'<nodeID://b8> {index} "2"{integer} .\n}} }}',
                      f'INSERT DATA {{ GRAPH <urn:x:layer> {{\n<nodeID://b9> {index} "3"{integer} .\n}} }}']
    embedded = [(q.subject, q.object) for q in lists.index_quads(layer)]
    assert [(str(c), str(n)) for c, n in embedded] == [(str(cells[i]), f'"{i + 1}"{integer}') for i in range(3)]
    assert _named_positions(lists, layer, "urn:other:") is None  # labels of another form: the store counts
    plain = Lists({ox.BlankNode("b0"): members[0]}, {ox.BlankNode("b0"): rdf})
    assert _named_positions(plain, layer, "nodeID://") is None
