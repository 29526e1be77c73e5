"""What particular stores are known to do wrong, by their ``Server`` header: one table.

A remote store names its software in the ``Server`` header of its answers. Where a store is known
(from tests/test_live_stores.py, run against the real servers) to answer a SPARQL question
otherwise than the standard or the embedded store does, that behaviour is one entry here: which
store, what it does, and what it affects -- a capability of :class:`~stepnc_graph.store.contract.Capabilities`
the store then lacks, or library queries whose answers it may get wrong. The store contract
(:mod:`stepnc_graph.store.remote`) and the query layer read the same table, so a store behaviour is
said once, and a caller never tests a server's name itself.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: the ``Server`` header of Virtuoso Open-Source 7 (``Virtuoso/07.20.3229 (Linux) ...``)
VIRTUOSO = re.compile(r"\s*Virtuoso/", re.IGNORECASE)


@dataclass(frozen=True)
class Behaviour:
    """A store's known departure from the answers the embedded store gives.

    ``server`` matches the store's ``Server`` header; ``does`` says what the store does (shown to
    the user with the answers it affects); ``capability`` is the
    :class:`~stepnc_graph.store.contract.Capabilities` field it makes false, if any; ``queries``
    are the library queries whose rows it may change; ``prologue`` is what the store takes before a
    request's operation to behave well instead (its own syntax), if anything."""

    server: re.Pattern[str]
    does: str
    capability: str | None = None
    queries: frozenset[str] = frozenset()
    prologue: str = ""

    def applies_to(self, server: str | None) -> bool:
        """Whether a store with this ``Server`` header behaves so (an unnamed store: no)."""
        return server is not None and self.server.match(server) is not None


#: every known behaviour (a new one: an entry here, and the live test that found it)
BEHAVIOURS: tuple[Behaviour, ...] = (
    # SPARQL leaves a GROUP_CONCAT's order to the store; Virtuoso 7.2 lists an ordered
    # sub-SELECT's values in an order of its own once the query joins
    Behaviour(VIRTUOSO, "does not keep the order of the values a GROUP_CONCAT joins",
              capability="ordered_group_concat"),
    # on a fresh Virtuoso 7.2 holding the test programs, 6 of 6 runs lost one row of this query's
    # joins; the same data on a server holding other data, on the embedded store and on
    # Oxigraph's server gave every row. The query layer does not ask such a store the query: it
    # answers it over a copy of the graphs it reads (querying.query._answered_from_a_copy)
    Behaviour(VIRTUOSO, "drops rows of this query's joins on some data (a defect of the store: the same data "
              "gives all rows on the embedded store and on Oxigraph's server)",
              queries=frozenset({"operations-per-feature"})),
    # the derived layer's blank values, 10k instances, in a load: 0.06 server CPU-s on a fresh
    # Virtuoso 7.2, 4.3-7.8 once it had held the program (a replacement, a load after an unload;
    # 12 loads), 0.05-0.09 in the same loads with Virtuoso's option to join as written
    Behaviour(VIRTUOSO, "may join a VALUES block last, by a nested loop over every quad of the graph, once it has "
              "held other data with those properties", capability="plans_joins",
              prologue='DEFINE sql:select-option "order"'),
)


def behaviours(server: str | None) -> list[Behaviour]:
    """The known behaviours of a store with this ``Server`` header."""
    return [b for b in BEHAVIOURS if b.applies_to(server)]


def lacks(server: str | None, capability: str) -> bool:
    """Whether a store with this ``Server`` header is known to lack ``capability``."""
    return any(b.capability == capability for b in behaviours(server))


def join_order_prologue(server: str | None) -> str:
    """What a store with this ``Server`` header takes before an operation to join its patterns in
    the order they are written ('' for none: the store plans its joins well by itself)."""
    return next((b.prologue for b in behaviours(server) if b.capability == "plans_joins" and b.prologue), "")


#: stores whose blank node labels, as their answers write them, name the node again when written
#: as an IRI in a later request (the label's form): Virtuoso 7 labels a node ``nodeID://b10576``
#: and reads ``<nodeID://b10576>`` in a query or an ``INSERT DATA`` as that node (tried: the node
#: an answer gave, written so into another graph, is the program's node there, ``isBlank`` true)
BLANK_NODE_IRIS: tuple[tuple[re.Pattern[str], str], ...] = ((VIRTUOSO, "nodeID://"),)


def blank_node_iri_prefix(server: str | None) -> str:
    """How the labels begin that a store with this ``Server`` header takes back as IRIs naming
    its blank nodes ('' for a store that takes none: a label holds within one answer only)."""
    return next((prefix for pattern, prefix in BLANK_NODE_IRIS if server is not None and pattern.match(server)), "")


def wrong_answers(server: str | None, query: str) -> list[Behaviour]:
    """The behaviours that may change the rows of the library query named ``query``."""
    return [b for b in behaviours(server) if query in b.queries]
