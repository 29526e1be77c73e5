"""Any SPARQL 1.1 store as the back end: the standard protocols only.

A :class:`RemoteStore` offers what the commands use of :class:`~stepnc_graph.store.GraphStore`
over three standard HTTP interfaces of a triple store (Oxigraph server, Apache
Jena Fuseki, GraphDB, Virtuoso, Amazon Neptune ...):

* SPARQL 1.1 Protocol, query (``query_url``): SELECT/ASK results as
  ``application/sparql-results+json`` (read with pyoxigraph, so rows are the same
  objects as the embedded store's), CONSTRUCT as N-Triples;
* SPARQL 1.1 Protocol, update (``update_url``): ``MOVE``, ``DROP``;
* SPARQL 1.1 Graph Store HTTP Protocol (``store_url``): ``POST`` N-Triples into a
  graph, ``GET`` a graph.

**A load is never half visible.** Its N-Triples go in bounded batches (flat
memory for any file) into a fresh staging graph; the file's graph and its
companions are replaced by one SPARQL Update request (``DROP SILENT GRAPH g ;
MOVE SILENT GRAPH staging TO g``), which a store runs as one transaction. An
interrupted load leaves the previous graph as it was, and at most a staging
graph that a later load of this tool drops once it is a day old. Transient
failures (connection errors, 429, 502, 503, 504) are retried with exponential
backoff.

**Credentials** come from the environment only -- ``STEPNC_GRAPH_ENDPOINT_TOKEN``
(a bearer token) or ``STEPNC_GRAPH_ENDPOINT_USER`` and
``STEPNC_GRAPH_ENDPOINT_PASSWORD`` (HTTP basic) -- never from a command line that
lands in shell history, and they are never printed (a URL holding a user or
password is refused). TLS certificates are verified; ``STEPNC_GRAPH_CA_BUNDLE``
names a CA file for a private PKI.
"""

from __future__ import annotations

import os
import re
import time
import uuid
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit, urlunsplit

import pyoxigraph as ox

from stepnc_graph.naming import STAGING, refuse_strangers
from stepnc_graph.store import Chunk, Companion, Shadow, StoreError, graph_layout

ENDPOINT_ENV = "STEPNC_GRAPH_ENDPOINT"
TOKEN_ENV = "STEPNC_GRAPH_ENDPOINT_TOKEN"
USER_ENV, PASSWORD_ENV = "STEPNC_GRAPH_ENDPOINT_USER", "STEPNC_GRAPH_ENDPOINT_PASSWORD"
CA_ENV = "STEPNC_GRAPH_CA_BUNDLE"
RETRIES_ENV = "STEPNC_GRAPH_RETRIES"
#: bytes of N-Triples per Graph Store Protocol request of a load
BATCH_BYTES = 8 << 20
#: a staging graph older than this was left by an interrupted load and is dropped
STALE_STAGING_SECONDS = 24 * 3600
#: the name of a staging graph of :meth:`RemoteStore.replace_graph`: its time, then a random id
_STAGING_NAME = re.compile(re.escape(STAGING) + r"([0-9]+):[0-9a-f]{32}")
_TRANSIENT = {429, 502, 503, 504}
_RESULTS_JSON = "application/sparql-results+json"
_NTRIPLES = "application/n-triples"
_TURTLE = "text/turtle"


class RemoteError(StoreError):
    """A request the remote store refused or could not answer (after the retries)."""


@dataclass(frozen=True)
class Endpoint:
    """Where a remote store answers: the three URLs, credentials from the environment, TLS."""

    query_url: str
    update_url: str
    store_url: str
    headers: dict[str, str] = field(default_factory=dict, repr=False)  # repr=False: never print credentials
    auth: tuple[str, str] | None = field(default=None, repr=False)
    verify: bool | str = True
    timeout: float = 300.0
    retries: int = 5

    @classmethod
    def from_options(cls, base: str, query_url: str | None = None, update_url: str | None = None,
                     store_url: str | None = None) -> "Endpoint":
        """URLs from a base (Oxigraph's layout: ``BASE/query``, ``BASE/update``, ``BASE/store``)
        or given one by one (Fuseki: ``/ds/query``, ``/ds/update``, ``/ds/data``)."""
        urls = [u for u in (base, query_url, update_url, store_url) if u]
        for url in urls:
            parts = urlsplit(url)
            if parts.scheme not in ("http", "https") or not parts.netloc:
                raise StoreError(f"endpoint {_safe(url)!r} is not an http(s) URL")
            if parts.username or parts.password:
                raise StoreError("an endpoint URL must not hold a user or password (they would land in shell "
                                 f"history): set {TOKEN_ENV}, or {USER_ENV} and {PASSWORD_ENV}")
        root = base.rstrip("/")
        if root.endswith("/query"):  # given the query endpoint itself: its siblings
            root = root[: -len("/query")]
        token, user, password = os.environ.get(TOKEN_ENV), os.environ.get(USER_ENV), os.environ.get(PASSWORD_ENV)
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        retries = os.environ.get(RETRIES_ENV, "").strip()
        return cls(query_url or f"{root}/query", update_url or f"{root}/update", store_url or f"{root}/store",
                   headers, (user, password or "") if user and not token else None,
                   os.environ.get(CA_ENV) or True, retries=int(retries) if retries.isdigit() else 5)

    def __str__(self) -> str:
        return _safe(self.query_url)


def _safe(url: str) -> str:
    """``url`` without user, password or query string (for messages)."""
    parts = urlsplit(url)
    host = parts.hostname or ""
    return urlunsplit((parts.scheme, host + (f":{parts.port}" if parts.port else ""), parts.path, "", ""))


def _value(term: Any) -> str:
    return str(term.value if hasattr(term, "value") else term)


def _batches(chunks: Iterable[Chunk], size: int) -> Iterator[tuple[str | None, bytes]]:
    """The chunks' text in UTF-8 batches of about ``size`` bytes (chunks end at triple boundaries),
    each with its graph: None for the main graph, a companion's name for its chunks (sent alone)."""
    pending: list[bytes] = []
    used = 0
    for chunk in chunks:
        if isinstance(chunk, Shadow):  # written by the load as quads (see Shadow)
            continue
        if isinstance(chunk, Companion):
            yield chunk.graph, chunk.text.encode("utf-8")
            continue
        data = chunk.encode("utf-8")
        pending.append(data)
        used += len(data)
        if used >= size:
            yield None, b"".join(pending)
            pending, used = [], 0
    if pending:
        yield None, b"".join(pending)


class RemoteStore:
    """Named graphs in a remote SPARQL 1.1 store (see the module docstring)."""

    path: Path | None = None  # not a directory: code that takes checkpoints or locks skips a remote store
    readonly = False
    last_removal: str | None = None

    def __init__(self, endpoint: Endpoint) -> None:
        import requests

        self.endpoint = endpoint
        self._http = requests.Session()
        self._http.headers.update(endpoint.headers)
        self._http.auth = endpoint.auth
        self._http.verify = endpoint.verify

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> "RemoteStore":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- HTTP ---------------------------------------------------------------------

    def _request(self, method: str, url: str, **kwargs: Any) -> Any:
        """One HTTP request, retried with backoff on transient failures; raises RemoteError."""
        import requests

        delay = 0.5
        for attempt in range(self.endpoint.retries + 1):
            try:
                response = self._http.request(method, url, timeout=self.endpoint.timeout, **kwargs)
            except (requests.ConnectionError, requests.Timeout) as e:
                failure = f"{type(e).__name__}: {_safe(url)} does not answer"
            else:
                if response.status_code < 400:
                    return response
                body = response.text[:300].strip()
                failure = f"{method} {_safe(url)} answered {response.status_code}: {body}"
                if response.status_code not in _TRANSIENT:
                    raise RemoteError(failure)
            if attempt < self.endpoint.retries:
                time.sleep(delay)
                delay *= 2
        raise RemoteError(f"{failure} (after {self.endpoint.retries + 1} attempts)")

    def update(self, sparql: str) -> None:
        """One SPARQL Update request (one transaction in the store)."""
        self._request("POST", self.endpoint.update_url, data=sparql.encode("utf-8"),
                      headers={"Content-Type": "application/sparql-update"})

    def _post_graph(self, graph: str, body: bytes, media_type: str = _NTRIPLES) -> None:
        self._request("POST", self.endpoint.store_url, params={"graph": graph}, data=body,
                      headers={"Content-Type": media_type})

    # -- writing --------------------------------------------------------------------

    def replace_graph(self, graph: str, chunks: Iterable[Chunk],
                      before_commit: Callable[[Callable[[str], str]], None] | None = None,
                      companions: Sequence[str] = ()) -> None:
        """Upload into staging graphs, then swap them in with one SPARQL Update request. Refuses
        what :meth:`GraphStore.replace_graph` refuses."""
        refuse_strangers(graph, companions)
        self._drop_stale_staging()
        stamp = int(time.time())
        staging = {name: f"{STAGING}{stamp}:{uuid.uuid4().hex}" for name in (graph, *companions)}
        try:
            for name, body in _batches(chunks, BATCH_BYTES):
                self._post_graph(staging[name or graph], body)
            if before_commit is not None:
                before_commit(lambda name: staging[name])
            # the swap: one request, so one transaction. ADD (a copy) and then dropping the
            # staging graph in a second request is MOVE's meaning; on Oxigraph 0.5 it keeps the
            # swap itself to a third of MOVE's time (measured: 700k quads, 21 s against 71 s)
            self.update(" ;\n".join(f"DROP SILENT GRAPH {ox.NamedNode(name)} ; ADD SILENT GRAPH <{tmp}> TO "
                                    f"{ox.NamedNode(name)}" for name, tmp in staging.items()))
        except BaseException:
            self._drop_quietly(staging.values())
            raise
        self._drop_quietly(staging.values())

    def _drop_quietly(self, graphs: Iterable[str]) -> None:
        """Drop staging graphs; if the server is gone, a later load drops them once stale."""
        try:
            self.update(" ; ".join(f"DROP SILENT GRAPH <{g}>" for g in graphs))
        except RemoteError:
            pass

    def _drop_stale_staging(self) -> None:
        """Drop the staging graphs an interrupted load left (named as :data:`_STAGING_NAME`, older
        than :data:`STALE_STAGING_SECONDS`). Never a graph that records itself as a program or a
        link graph: no load takes a staging name now (:data:`~stepnc_graph.naming.RESERVED`), but
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
        for _, body in _batches([text], BATCH_BYTES):
            self._post_graph(graph, body)

    def add_turtle(self, graph: str, text: str) -> None:
        self._post_graph(graph, text.encode("utf-8"), _TURTLE)

    def remove_graph(self, graph: str, companions: Sequence[str] = (), compact: bool = False) -> bool:
        """Drop ``graph`` and its ``companions``; the endpoint manages its own storage, so
        ``compact`` asks nothing of it. Refuses what :meth:`replace_graph` refuses."""
        refuse_strangers(graph, companions)
        if not self.has_graph(graph):
            return False
        self.update(" ; ".join(f"DROP SILENT GRAPH {ox.NamedNode(name)}" for name in (graph, *companions)))
        return True

    # -- reading ----------------------------------------------------------------------

    def query(self, sparql: str, **options: Any) -> Any:
        """SPARQL over the protocol; SELECT/ASK rows are pyoxigraph's, CONSTRUCT gives Triples.

        The options are pyoxigraph's, in standard terms: the dataset goes as
        ``default-graph-uri`` / ``named-graph-uri`` (the union default graph is every
        graph named as default), ``prefixes`` as PREFIX lines, and ``substitutions`` as
        a VALUES clause at the end of the query, each term written by pyoxigraph (so a
        value can never change the query's text).
        """
        unknown = set(options) - {"use_default_graph_as_union", "default_graph", "named_graphs", "prefixes",
                                  "substitutions"}
        if unknown:
            raise StoreError(f"query options {sorted(unknown)} are not available over the SPARQL protocol")
        prefixes: dict[str, str] | None = options.get("prefixes")
        substitutions: dict[Any, Any] | None = options.get("substitutions")
        default_graph: Sequence[Any] | None = options.get("default_graph")
        named_graphs: Sequence[Any] | None = options.get("named_graphs")
        if prefixes:
            sparql = "".join(f"PREFIX {p}: <{iri}>\n" for p, iri in prefixes.items()) + sparql
        if substitutions:
            names = " ".join(str(v) for v in substitutions)
            sparql += f"\nVALUES ({names}) {{ ({' '.join(str(t) for t in substitutions.values())}) }}"
        if options.get("use_default_graph_as_union") and default_graph is None:
            default_graph = [ox.NamedNode(g) for g in self.all_graphs()]
        form: list[tuple[str, str]] = [("query", sparql)]
        form += [("default-graph-uri", _value(g)) for g in default_graph or ()]
        form += [("named-graph-uri", _value(g)) for g in named_graphs or ()]
        response = self._request("POST", self.endpoint.query_url, data=form,
                                 headers={"Accept": f"{_RESULTS_JSON}, {_NTRIPLES};q=0.9"})
        kind = response.headers.get("Content-Type", "").split(";")[0].strip()
        if kind == _NTRIPLES or kind.endswith("turtle"):
            fmt = ox.RdfFormat.N_TRIPLES if kind == _NTRIPLES else ox.RdfFormat.TURTLE
            return list(ox.parse(response.content, fmt))
        return ox.parse_query_results(response.content, ox.QueryResultsFormat.JSON)

    def _all_graphs(self) -> list[str]:
        rows = self.query("SELECT DISTINCT ?g WHERE { GRAPH ?g { } }")  # the graph names, no scan
        return [row[0].value for row in rows if isinstance(row[0], ox.NamedNode)]

    def all_graphs(self) -> list[str]:
        """Every named graph but staging ones."""
        return sorted(g for g in self._all_graphs() if not g.startswith(STAGING))

    def graphs(self) -> list[str]:
        """The loaded files' graphs (and graphs `link` or users added): not the vocabulary graph or a
        program's derived layer, as :meth:`GraphStore.graphs`."""
        return graph_layout(self).listed()

    def has_graph(self, graph: str) -> bool:
        return bool(self.query(f"ASK {{ GRAPH {ox.NamedNode(graph)} {{ ?s ?p ?o }} }}"))

    def count(self, graph: str | None = None) -> int:
        pattern = f"GRAPH {ox.NamedNode(graph)} {{ ?s ?p ?o }}" if graph else "{ ?s ?p ?o } UNION { GRAPH ?g { ?s ?p ?o } }"
        [row] = list(self.query(f"SELECT (COUNT(*) AS ?n) WHERE {{ {pattern} }}"))
        return int(row[0].value)

    def quads(self, graph: str | None = None) -> Iterator[ox.Quad]:
        """A graph's quads (Graph Store Protocol GET); every graph's for None."""
        for name in [graph] if graph else self.all_graphs():
            assert name is not None
            response = self._request("GET", self.endpoint.store_url, params={"graph": name},
                                     headers={"Accept": _NTRIPLES}, stream=True)
            response.raw.decode_content = True  # streamed: a large graph is never all in memory
            g = ox.NamedNode(name)
            with response:
                for t in ox.parse(response.raw, ox.RdfFormat.N_TRIPLES):
                    yield ox.Quad(t.subject, t.predicate, t.object, g)

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


def open_remote(base: str | None = None, query_url: str | None = None, update_url: str | None = None,
                store_url: str | None = None) -> RemoteStore:
    """The remote store at ``base`` (default ``$STEPNC_GRAPH_ENDPOINT``), checked to answer."""
    base = base or os.environ.get(ENDPOINT_ENV) or query_url
    if not base:
        raise StoreError(f"no endpoint: give --endpoint URL or set {ENDPOINT_ENV}")
    store = RemoteStore(Endpoint.from_options(base, query_url, update_url, store_url))
    store.query("ASK { ?s ?p ?o }")  # fail now, with a clear message, if it does not answer
    return store
