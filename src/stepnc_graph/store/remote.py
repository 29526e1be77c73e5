"""Any SPARQL 1.1 store as the back end: the standard protocols only.

A :class:`RemoteStore` offers what the commands use of :class:`~stepnc_graph.store.GraphStore`
over three standard HTTP interfaces of a triple store (Oxigraph server, Apache
Jena Fuseki, GraphDB, Virtuoso, Amazon Neptune ...):

* SPARQL 1.1 Protocol, query (``query_url``): SELECT/ASK results as
  ``application/sparql-results+json`` (read with pyoxigraph, so rows are the same
  objects as the embedded store's), CONSTRUCT as N-Triples;
* SPARQL 1.1 Protocol, update (``update_url``): ``ADD``, ``DROP``, ``INSERT DATA``;
* SPARQL 1.1 Graph Store HTTP Protocol (``store_url``): ``POST`` N-Triples into a
  graph or N-Quads into the store, ``GET`` a graph.

**A load is never half visible.** On a server that loads an N-Quads POST in one transaction
(:data:`_DATASET_POST`) the load is staged in the client, in an in-memory store, and written by
one request: an N-Quads POST of graphs that do not exist yet; for a replacement, one SPARQL Update
of what changed alone, conditional on the last load's id
(:mod:`~stepnc_graph.store.remote_difference`), else one that drops and inserts the graphs. Elsewhere its N-Triples go in bounded batches into fresh staging graphs of
the store, and the file's graph and its companions are replaced by one SPARQL Update request
(``DROP SILENT GRAPH g ; ADD SILENT GRAPH staging TO g``), which a store runs as one transaction.
An interrupted load leaves the previous graph as it was, and at most a staging graph that a later
load of this tool drops once it is a day old. Transient
failures (connection errors, 429, 502, 503, 504) are retried with exponential backoff -- but not
a request the endpoint may have carried out already: one that wrote (an update, a Graph Store
POST) and got no answer within the timeout is reported, not sent again.

**Answers are checked.** Each request waits at most ``timeout`` seconds for the
whole answer (``--timeout``, ``$STEPNC_GRAPH_TIMEOUT``, default 120). A query's
answer must be what the query asks for -- SPARQL results with the variables it
selects, a boolean for ASK, RDF for CONSTRUCT (Oxigraph parses the query first, on
an empty store, to know) -- and a complete document: a login page, a cut JSON
document or another query's variables are an error naming the endpoint, never
rows. Parameters are bound inside the query's groups (:mod:`stepnc_graph.store.bindings`),
so FILTERs see them as they do in the embedded store.

**Credentials** come from the environment only -- ``STEPNC_GRAPH_ENDPOINT_TOKEN``
(a bearer token) or ``STEPNC_GRAPH_ENDPOINT_USER`` and
``STEPNC_GRAPH_ENDPOINT_PASSWORD`` (HTTP basic) -- never from a command line that
lands in shell history, and they are never printed (a URL holding a user or
password is refused), and no error message shows them, even one whose body
echoes the request. TLS certificates are verified; ``STEPNC_GRAPH_CA_BUNDLE``
names a CA file for a private PKI, and wins over ``REQUESTS_CA_BUNDLE`` and
``CURL_CA_BUNDLE`` (which apply when it is not set).
"""

from __future__ import annotations

import os
import re
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph.store.bindings import bind_in_groups
from stepnc_graph.core.naming import STAGING, graph_layout, refuse_strangers
from stepnc_graph.store import StoreError
from stepnc_graph.store.behaviour import blank_node_iri_prefix, join_order_prologue, lacks
from stepnc_graph.store.contract import Capabilities, Chunk
from stepnc_graph.store.answers import (
    RemoteError,
    _answer,
    _expected,
    _kind,
    system_graph,
)
from stepnc_graph.store.remote_difference import token_graph
from stepnc_graph.store.remote_http import HttpClient
from stepnc_graph.store.remote_load import BATCH_BYTES, _batches, replace_from_client, replace_in_store
from stepnc_graph.store.endpoint import (
    AUTH_ENV,
    DEFAULT_TIMEOUT,
    ENDPOINT_ENV,
    Endpoint,
)

__all__ = ["AUTH_ENV", "DEFAULT_TIMEOUT", "ENDPOINT_ENV", "Endpoint", "RemoteError", "RemoteStore", "StoreError",
           "open_remote"]

#: a staging graph older than this was left by an interrupted load and is dropped
STALE_STAGING_SECONDS = 24 * 3600
#: the name of a staging graph of :meth:`RemoteStore.replace_graph`: its time, then a random id
_STAGING_NAME = re.compile(re.escape(STAGING) + r"([0-9]+):[0-9a-f]{32}")
_RESULTS_JSON = "application/sparql-results+json"
_NTRIPLES = "application/n-triples"
_TURTLE = "text/turtle"


def _value(term: Any) -> str:
    return str(term.value if hasattr(term, "value") else term)


#: servers (by their ``Server`` header) that load an N-Quads document POSTed to the Graph Store
#: endpoint (no ``graph`` parameter) in one transaction: the whole document or, on any failure (a
#: parse error, a body cut short by a client that died, the server killed), nothing. Oxigraph's
#: server does (its ``/store``); Virtuoso 7 answers such a POST 200 and loads nothing, and its
#: Graph Store POST of one graph keeps the triples before an error, and a part of them when the
#: server is killed mid-request (100,000 triples, kill -9 half-way: 19,999 kept after the restart;
#: found by trying)
_DATASET_POST = re.compile(r"\s*Oxigraph/", re.IGNORECASE)
_NQUADS = "application/n-quads"
#: Oxigraph's server and its version, from its ``Server`` header
_OXIGRAPH_VERSION = re.compile(r"\s*Oxigraph/([0-9]+)\.([0-9]+)", re.IGNORECASE)


def atomic_bulk_post(server: str | None) -> bool:
    """Whether a server (by its ``Server`` header) loads an N-Quads POST with its bulk loader
    (``?no_transaction``) in one atomic step too: Oxigraph's server from 0.5 builds sorted index
    files from the whole body and adds them to its database in one step at the end, so a parse
    error, a body cut short or the server killed at any point keeps nothing (tried: 1.2M quads
    with a bad last line, a client gone mid-body, kill -9 at 0.3-1.0 of a 1.5M-quad load). It
    costs the server a third to a half of the transactional insert's CPU (150k quads: 1.4 against
    3.2 CPU-s), which writes every quad into each index one by one. Oxigraph 0.4 added the files
    batch by batch."""
    found = _OXIGRAPH_VERSION.match(server or "")
    return found is not None and (int(found.group(1)), int(found.group(2))) >= (0, 5)




class RemoteStore:
    """Named graphs in a remote SPARQL 1.1 store (see the module docstring)."""

    path: Path | None = None  # not a directory: code that takes checkpoints or locks skips a remote store
    readonly = False
    last_removal: str | None = None

    def __init__(self, endpoint: Endpoint) -> None:
        self.endpoint = endpoint
        #: True once the store answered the scan-free graph listing wrongly (see :meth:`_all_graphs`)
        self._graph_listing_scans: bool | None = None
        self._http = HttpClient(endpoint)
        #: while a load is staged in the client (:func:`~stepnc_graph.store.remote_load.replace_from_client`): the in-memory
        #: store and the staging names it holds; every read or write naming one of them goes there
        self._local: tuple[Any, dict[str, str]] | None = None
        #: while a load staged in the store runs its ``before_commit`` (:func:`~stepnc_graph.store.remote_load.replace_in_store`):
        #: the client's in-memory copy of the program's staging graph and its name; reads naming it go there
        self._copy: tuple[Any, str] | None = None
        self._own = threading.local()  # .labels: this thread's reads go to the server (own_labels)

    def prepare_to_write(self) -> None:
        """Nothing to take: the endpoint orders concurrent updates itself."""

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> "RemoteStore":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- HTTP ---------------------------------------------------------------------

    def _request(self, method: str, url: str, *, idempotent: bool = True, stream: bool = False,
                 **kwargs: Any) -> tuple[Any, bytes | None]:
        """One HTTP request and its answer's body (None when ``stream``): see :meth:`HttpClient.request`."""
        return self._http.request(method, url, idempotent=idempotent, stream=stream, **kwargs)

    def _staged(self, graph: str | None = None, sparql: str = "", graphs: Iterable[Any] = (), write: bool = False) -> Any:
        """The in-memory store of a load staged in the client (:func:`~stepnc_graph.store.remote_load.replace_from_client`) when a
        request names one of its staging graphs -- as ``graph``, in ``sparql`` or among a query's
        dataset ``graphs`` -- or, unless it would ``write``, the client's copy of a load staged in
        the store (:attr:`_copy`) when it names that graph; else None (the request goes to the server)."""
        if self._local is not None:
            local, names = self._local[0], set(self._local[1].values())
        elif self._copy is not None and not write and not getattr(self._own, "labels", False):
            local, names = self._copy[0], {self._copy[1]}
        else:
            return None
        if graph in names or any(_value(g) in names for g in graphs) or any(n in sparql for n in names):
            return local
        return None

    @contextmanager
    def own_labels(self) -> Iterator[None]:
        """Reads in this block, on this thread, go to the server, not to the client's copy of a
        graph staged there (:attr:`_copy`): for answers whose blank node labels must be the store's
        own (other threads go on reading the copy meanwhile)."""
        self._own.labels = True
        try:
            yield
        finally:
            self._own.labels = False

    def update(self, sparql: str) -> None:
        """One SPARQL Update request (one transaction in the store)."""
        if (local := self._staged(sparql=sparql, write=True)) is not None:
            local.update(sparql)
            return
        self._request("POST", self.endpoint.update_url, idempotent=False, data=sparql.encode("utf-8"),
                      headers={"Content-Type": "application/sparql-update"})

    def _post_graph(self, graph: str, body: bytes, media_type: str = _NTRIPLES) -> None:
        self._request("POST", self.endpoint.store_url, idempotent=False, params={"graph": graph}, data=body,
                      headers={"Content-Type": media_type})

    # -- writing --------------------------------------------------------------------

    def replace_graph(self, graph: str, chunks: Iterable[Chunk],
                      before_commit: Callable[[Callable[[str], str]], None] | None = None,
                      companions: Sequence[str] = ()) -> None:
        """Atomically make ``graph`` (and ``companions``) what ``chunks`` and ``before_commit``
        write; refuses what :meth:`GraphStore.replace_graph` refuses.

        On a server that loads an N-Quads POST in one transaction (:data:`_DATASET_POST`) the load
        is staged in the client and sent in one request (:func:`~stepnc_graph.store.remote_load.replace_from_client`); elsewhere
        it is staged in the store and swapped in by one SPARQL Update (:func:`~stepnc_graph.store.remote_load.replace_in_store`)."""
        refuse_strangers(graph, companions)
        self._drop_stale_staging()
        if _DATASET_POST.match(self.server or ""):
            replace_from_client(self, graph, chunks, before_commit, companions)
        else:
            replace_in_store(self, graph, chunks, before_commit, companions)

    def _post_dataset(self, body: Iterable[bytes]) -> None:
        """One N-Quads POST of graphs that do not exist yet (a new program's, fresh staging graphs),
        by the server's bulk loader where that is atomic too (:func:`atomic_bulk_post`)."""
        self._request("POST", self.endpoint.store_url, idempotent=False, data=body,
                      params={"no_transaction": ""} if atomic_bulk_post(self.server) else None,
                      headers={"Content-Type": _NQUADS})

    def _drop_quietly(self, graphs: Iterable[str]) -> None:
        """Drop staging graphs, each by a request of its own, side by side (nothing is swapped in
        any more: they need no one transaction, and a store may drop them on several cores; Virtuoso
        7.2, a replicated 10k program's two: 0.57-0.98 s wall where one request took 0.96-1.04); if
        the server is gone, a later load drops them once stale."""
        def drop(graph: str) -> None:
            try:
                self.update(f"DROP SILENT GRAPH <{graph}>")
            except RemoteError:
                pass

        with ThreadPoolExecutor(max_workers=4, thread_name_prefix="stepnc-graph drop") as pool:
            list(pool.map(drop, dict.fromkeys(graphs)))

    def _drop_stale_staging(self) -> None:
        """Drop the staging graphs an interrupted load left (named as :data:`_STAGING_NAME`, older
        than :data:`STALE_STAGING_SECONDS`). Never a graph that records itself as a program or a
        link graph: no load takes a staging name now (:data:`~stepnc_graph.core.naming.RESERVED`), but
        an older stepnc-graph let a program be loaded under one."""
        limit = time.time() - STALE_STAGING_SECONDS
        stale = [g for g in self._all_graphs()
                 if (m := _STAGING_NAME.fullmatch(g)) is not None and int(m.group(1)) < limit]
        if stale:
            recorded = graph_layout(self)  # its records cover staging names too
            stale = [g for g in stale if g not in recorded.programs and g not in recorded.links]
        if stale:
            self.update(" ; ".join(f"DROP SILENT GRAPH <{g}>" for g in stale))

    def add_ntriples(self, graph: str, text: str, bulk: bool = False) -> None:
        if (local := self._staged(graph)) is not None:
            local.add_ntriples(graph, text, bulk)
            if self._local is not None:
                return  # else the client's copy of a graph staged in the store: the store's graph too
        for _, body in _batches([text], BATCH_BYTES):
            self._post_graph(graph, body)

    def add_turtle(self, graph: str, text: str) -> None:
        if (local := self._staged(graph, write=True)) is not None:
            local.add_turtle(graph, text)
            return
        self._post_graph(graph, text.encode("utf-8"), _TURTLE)

    def remove_graph(self, graph: str, companions: Sequence[str] = (), compact: bool = False) -> bool:
        """Drop ``graph`` and its ``companions``; the endpoint manages its own storage, so
        ``compact`` asks nothing of it. Refuses what :meth:`replace_graph` refuses."""
        refuse_strangers(graph, companions)
        if not self.has_graph(graph):
            return False
        self.update(" ; ".join(f"DROP SILENT GRAPH {ox.NamedNode(name)}"
                               for name in (graph, *companions, token_graph(graph))))
        return True

    # -- reading ----------------------------------------------------------------------

    def query(self, sparql: str, **options: Any) -> Any:
        """SPARQL over the protocol; SELECT/ASK rows are pyoxigraph's, CONSTRUCT gives Triples.

        The options are pyoxigraph's, in standard terms: the dataset goes as
        ``default-graph-uri`` / ``named-graph-uri`` (the union default graph is every
        graph named as default), ``prefixes`` as PREFIX lines, and ``substitutions`` as
        a VALUES block opening each group the variable reaches (:mod:`stepnc_graph.store.bindings`),
        each term written by pyoxigraph (so a value can never change the query's text).

        Oxigraph parses the query first, on an empty store: a syntax error is raised as the
        embedded store raises it, and the answer must have the form and the variables that
        parse gives (RemoteError otherwise).
        """
        unknown = set(options) - {"use_default_graph_as_union", "default_graph", "named_graphs", "prefixes",
                                  "substitutions"}
        if unknown:
            raise StoreError(f"query options {sorted(unknown)} are not available over the SPARQL protocol")
        prefixes: dict[str, str] | None = options.get("prefixes")
        substitutions: dict[Any, Any] | None = options.get("substitutions")
        default_graph: Sequence[Any] | None = options.get("default_graph")
        named_graphs: Sequence[Any] | None = options.get("named_graphs")
        if (local := self._staged(sparql=sparql, graphs=[*(default_graph or ()), *(named_graphs or ())])) is not None:
            return local.query(sparql, **options)
        expected = _expected(sparql, prefixes, substitutions)
        if substitutions:
            bound = bind_in_groups(sparql, {v.value: str(t) for v, t in substitutions.items()})
            try:
                fits = expected is None or _expected(bound, prefixes, None) == expected
            except SyntaxError:
                fits = False
            if not fits:
                raise StoreError(f"parameters {', '.join(str(v) for v in substitutions)} cannot be bound inside this "
                                 "query for a SPARQL endpoint (does the query BIND them itself?)")
            sparql = bound
        if prefixes:
            sparql = "".join(f"PREFIX {p}: <{iri}>\n" for p, iri in prefixes.items()) + sparql
        if options.get("use_default_graph_as_union") and default_graph is None:
            # the embedded store's meaning, said in full: its graphs as the default graph, and
            # (unless given) as the named graphs -- a store asked for a default graph alone may
            # take every graph it has as named graphs (Virtuoso: its system graphs too), or none
            default_graph = [ox.NamedNode(g) for g in self.all_graphs()]
            if named_graphs is None:
                named_graphs = default_graph
        form: list[tuple[str, str]] = [("query", sparql)]
        form += [("default-graph-uri", _value(g)) for g in default_graph or ()]
        form += [("named-graph-uri", _value(g)) for g in named_graphs or ()]
        response, content = self._request("POST", self.endpoint.query_url, data=form,
                                          headers={"Accept": f"{_RESULTS_JSON}, {_NTRIPLES};q=0.9"})
        return _answer(str(self.endpoint), response.headers.get("Content-Type", ""), content or b"", expected)

    def _all_graphs(self) -> list[str]:
        """The names of the store's non-empty named graphs, the store's own system graphs left out.

        ``GRAPH ?g { }`` lists the names without a scan, but several stores answer it wrongly
        (Virtuoso, RDF4J/GraphDB, Comunica, Oxigraph before 0.4.7: one unbound row, or none):
        an answer holding an unbound row, or no row on a store that has quads in a named graph,
        is replaced by the answer of ``GRAPH ?g { ?s ?p ?o }`` grouped by ``?g``, which every store
        gets right (the store's answer is remembered for the next listings)."""
        if self._graph_listing_scans is None:
            rows = list(self.query("SELECT DISTINCT ?g WHERE { GRAPH ?g { } }"))
            wrong = any(not isinstance(row[0], ox.NamedNode) for row in rows) or (
                not rows and bool(self.query("ASK { GRAPH ?g { ?s ?p ?o } }")))
            if not wrong:
                return [g for g in (row[0].value for row in rows) if not system_graph(g)]
            self._graph_listing_scans = True
        # GROUP BY, not DISTINCT: the same answer, but Virtuoso 7 takes 50 s for DISTINCT over a
        # few thousand quads and 0.07 s for GROUP BY
        rows = self.query("SELECT ?g WHERE { GRAPH ?g { ?s ?p ?o } } GROUP BY ?g")
        return [row[0].value for row in rows if isinstance(row[0], ox.NamedNode) and not system_graph(row[0].value)]

    def all_graphs(self) -> list[str]:
        """Every named graph but staging ones and the store's own system graphs (:func:`system_graph`)."""
        return sorted(g for g in self._all_graphs() if not g.startswith(STAGING))

    def has_graph(self, graph: str) -> bool:
        if (local := self._staged(graph)) is not None:
            return bool(local.has_graph(graph))
        return bool(self.query(f"ASK {{ GRAPH {ox.NamedNode(graph)} {{ ?s ?p ?o }} }}"))

    def count(self, graph: str | None = None) -> int:
        """The triples of ``graph``; of every graph :meth:`all_graphs` lists for None (a store's
        default graph may be the union of its graphs, its system graphs included: not counted)."""
        if graph is None:
            return sum(self.count(g) for g in self.all_graphs())
        if (local := self._staged(graph)) is not None:
            return int(local.count(graph))
        [row] = list(self.query(f"SELECT (COUNT(*) AS ?n) WHERE {{ GRAPH {ox.NamedNode(graph)} {{ ?s ?p ?o }} }}"))
        return int(row[0].value)

    def _get_graph(self, graph: str, stream: bool) -> tuple[Any, bytes | None]:
        """The Graph Store Protocol GET of ``graph`` as N-Triples: the response (and its content,
        unless ``stream``), checked to be N-Triples (RemoteError otherwise, the response closed)."""
        response, content = self._request("GET", self.endpoint.store_url, params={"graph": graph},
                                          headers={"Accept": _NTRIPLES}, stream=stream)
        media_type = response.headers.get("Content-Type", "").split(";")[0].strip().lower()
        if media_type != _NTRIPLES:
            response.close()
            raise RemoteError(f"{self.endpoint.store_url} answered {_kind(media_type)} for graph {graph}, "
                              f"where N-Triples ({_NTRIPLES}) were expected")
        return response, content

    def ntriples(self, graph: str) -> bytes:
        """A graph's N-Triples as the store writes them (Graph Store Protocol GET); empty if it has none."""
        if not self.has_graph(graph):
            return b""
        return self._get_graph(graph, stream=False)[1] or b""

    def kept_text(self, graph: str, path: Path, store_labels: bool = True) -> bool:
        """False: an endpoint keeps no load's text here (its graphs are read over the protocol)."""
        return False

    def quads(self, graph: str | None = None) -> Iterator[ox.Quad]:
        """A graph's quads (Graph Store Protocol GET); every graph's for None."""
        if graph is not None and (local := self._staged(graph)) is not None:
            yield from local.quads(graph)
            return
        for name in [graph] if graph else self.all_graphs():
            assert name is not None
            response, _ = self._get_graph(name, stream=True)
            response.raw.decode_content = True  # streamed: a large graph is never all in memory
            g = ox.NamedNode(name)
            with response:
                try:
                    for t in ox.parse(response.raw, ox.RdfFormat.N_TRIPLES):
                        yield ox.Quad(t.subject, t.predicate, t.object, g)
                except SyntaxError as exc:
                    raise RemoteError(f"{self.endpoint.store_url} answered graph {name} with N-Triples that do not "
                                      f"parse (cut short?): {exc}") from None

    def quads_for_pattern(self, subject: Any, predicate: Any, obj: Any, graph: Any = None) -> Iterator[ox.Quad]:
        """The quads matching a pattern (None: any term), as the embedded store's method: one
        SELECT per graph (``graph`` None: every graph :meth:`all_graphs` lists). A blank node
        cannot be asked for: its label means nothing to the store in another request."""
        if graph is not None and (local := self._staged(_value(graph))) is not None:
            yield from local.quads_for_pattern(subject, predicate, obj, graph)
            return
        given = {"s": subject, "p": predicate, "o": obj}
        if any(isinstance(term, ox.BlankNode) for term in given.values()):
            raise StoreError(f"{self.endpoint} is a remote store: a blank node cannot be looked up by its label")
        pattern = " ".join(str(term) if term is not None else f"?{name}" for name, term in given.items())
        names = [ox.NamedNode(_value(graph))] if graph is not None else [ox.NamedNode(g) for g in self.all_graphs()]
        for name in names:
            for row in self.query(f"SELECT ?s ?p ?o WHERE {{ GRAPH {name} {{ {pattern} }} }}"):
                yield ox.Quad(subject or row["s"], predicate or row["p"], obj or row["o"], name)

    def local_copy(self, graphs: str | Sequence[str] | None = None) -> Any:
        """An in-memory :class:`GraphStore` holding ``graphs`` (one, several, or every graph): for
        work that walks a graph node by node (canonical exports, validation), which one request
        per node would make slow. It holds the graphs in memory."""
        from stepnc_graph.store import GraphStore

        copy = GraphStore(None)
        for name in [graphs] if isinstance(graphs, str) or graphs is None else graphs:
            copy.oxigraph.bulk_extend(self.quads(name))
        return copy

    @property
    def oxigraph(self) -> ox.Store:
        raise StoreError(f"{self.endpoint} is a remote store: it has no embedded Oxigraph database")

    # -- the store contract (stepnc_graph.store.contract) --------------------------------

    #: persistent; blank nodes cannot be named across requests, reads are requests, and the
    #: endpoint manages its own storage
    @property
    def capabilities(self) -> Capabilities:
        """An endpoint's: persistent, read and written through requests; whether its GROUP_CONCAT
        keeps the order of its values is known once it has answered (by its ``Server`` header, from
        the table of :mod:`stepnc_graph.store.behaviour`)."""
        return Capabilities(persistent=True, blank_node_writes=False, local_reads=False, compactable=False,
                            ordered_group_concat=not lacks(self.server, "ordered_group_concat"),
                            plans_joins=not lacks(self.server, "plans_joins"),
                            join_order_prologue=join_order_prologue(self.server),
                            blank_node_iri_prefix=blank_node_iri_prefix(self.server))

    @property
    def server(self) -> str | None:
        """The endpoint's ``Server`` header, from its first answer that named one."""
        return self._http.server

    @property
    def location(self) -> str:
        return str(self.endpoint)

    def maintenance(self) -> None:
        """None: the endpoint manages its own storage."""
        return None

    def compact(self, progress: Callable[[int, int], None] | None = None) -> None:
        raise StoreError("compact works on a stepnc-graph store directory; a SPARQL endpoint manages its own storage")

    def add_quads(self, quads: Iterable[ox.Quad]) -> int:
        raise StoreError(f"{self.endpoint} is a remote store: quads with blank nodes cannot be sent to it as they "
                         "are (see Capabilities.blank_node_writes)")




def open_remote(base: str | None = None, query_url: str | None = None, update_url: str | None = None,
                store_url: str | None = None, timeout: float | None = None) -> RemoteStore:
    """The remote store at ``base`` (default ``$STEPNC_GRAPH_ENDPOINT``), checked to answer;
    ``timeout`` is the seconds one request may take (default ``$STEPNC_GRAPH_TIMEOUT``, else 120)."""
    base = base or os.environ.get(ENDPOINT_ENV) or query_url
    if not base:
        raise StoreError(f"no endpoint: give --endpoint URL or set {ENDPOINT_ENV}")
    store = RemoteStore(Endpoint.from_options(base, query_url, update_url, store_url, timeout))
    store.query("ASK { ?s ?p ?o }")  # fail now, with a clear message, if it does not answer
    return store
