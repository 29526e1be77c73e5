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
one request: an N-Quads POST of graphs that do not exist yet, or one SPARQL Update that drops and
inserts a replacement. Elsewhere its N-Triples go in bounded batches into fresh staging graphs of
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
import time
import uuid
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph.store.bindings import bind_in_groups
from stepnc_graph.core.naming import STAGING, VOCABULARY_GRAPH, graph_layout, refuse_strangers
from stepnc_graph.store import StoreError
from stepnc_graph.store.contract import Capabilities, Chunk, Companion, Shadow
from stepnc_graph.store.answers import (
    _XSD_DOUBLE,
    _DOUBLE,
    RemoteError,
    _answer,
    _expected,
    _kind,
    _number,
    system_graph,
)
from stepnc_graph.store.endpoint import (
    AUTH_ENV,
    CA_ENV,
    CONNECT_TIMEOUT,
    DEFAULT_TIMEOUT,
    ENDPOINT_ENV,
    TIMEOUT_ENV,
    Endpoint,
    _safe,
)

__all__ = ["AUTH_ENV", "DEFAULT_TIMEOUT", "ENDPOINT_ENV", "Endpoint", "RemoteError", "RemoteStore", "StoreError",
           "open_remote"]

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


class _NQuadsBody:
    """The graphs of an in-memory store as one N-Quads request body, renamed by ``names`` (staged
    name -> name in the server), made in pieces while it is sent (chunked transfer: no copy of
    the whole document in memory). Iterable again from the start: a request sent again (no
    connection was made the first time) sends the whole document again, never a spent one."""

    #: triples serialized at a time
    piece = 50_000

    def __init__(self, local: Any, names: dict[str, str], update: str | None = None) -> None:
        self.local, self.names, self.update = local, names, update

    def __iter__(self) -> Iterator[bytes]:
        if self.update is not None:
            yield self.update.encode("utf-8") + b" ;\nINSERT DATA {\n"
        for staged, name in self.names.items():
            into = ox.NamedNode(name)
            if self.update is not None:
                yield f"GRAPH {into} {{\n".encode()
            triples: list[ox.Triple] = []
            for q in self.local.oxigraph.quads_for_pattern(None, None, None, ox.NamedNode(staged)):
                triples.append(q.triple)
                if len(triples) >= self.piece:
                    yield self._text(triples, into)
                    triples = []
            if triples:
                yield self._text(triples, into)
            if self.update is not None:
                yield b"}\n"
        if self.update is not None:
            yield b"}\n"

    def _text(self, triples: list[ox.Triple], into: ox.NamedNode) -> bytes:
        text = ox.serialize(triples, format=ox.RdfFormat.N_TRIPLES) or b""
        if self.update is not None:
            return text
        # N-Quads: each N-Triples line with the graph before its final " ."
        return text.replace(b" .\n", f" {into} .\n".encode())


#: servers (by their ``Server`` header) whose GROUP_CONCAT does not keep the order its values
#: reach it in (found by tests/test_live_stores.py: Virtuoso 7.2 lists an ordered sub-SELECT's
#: values in an order of its own once the query joins)
_UNORDERED_CONCAT = re.compile(r"\s*Virtuoso/", re.IGNORECASE)


#: servers (by their ``Server`` header) that load an N-Quads document POSTed to the Graph Store
#: endpoint (no ``graph`` parameter) in one transaction: the whole document or, on any failure (a
#: parse error, a body cut short by a client that died, the server killed), nothing. Oxigraph's
#: server does (its ``/store``); Virtuoso 7 answers such a POST 200 and loads nothing, and its
#: Graph Store POST of one graph keeps the triples before an error (found by trying both)
_DATASET_POST = re.compile(r"\s*Oxigraph/", re.IGNORECASE)
_NQUADS = "application/n-quads"
#: the lexical form of each xsd:double literal in N-Triples text (see answers._DOUBLE)
_DOUBLE_TEXT = re.compile(_DOUBLE.pattern.decode())


def _software(header: str) -> str | None:
    """A ``Server`` header as text fit for a message: no control characters, at most 120 long."""
    return re.sub(r"[\x00-\x1f\x7f]", "", header).strip()[:120] or None


class RemoteStore:
    """Named graphs in a remote SPARQL 1.1 store (see the module docstring)."""

    path: Path | None = None  # not a directory: code that takes checkpoints or locks skips a remote store
    readonly = False
    last_removal: str | None = None

    def __init__(self, endpoint: Endpoint) -> None:
        import requests

        self.endpoint = endpoint
        #: True once the store answered the scan-free graph listing wrongly (see :meth:`_all_graphs`)
        self._graph_listing_scans: bool | None = None
        self._http = requests.Session()
        self._http.headers.update(endpoint.headers)
        self._server: str | None = None
        #: while a load is staged in the client (:meth:`_replace_from_client`): the in-memory
        #: store and the staging names it holds; every read or write naming one of them goes there
        self._local: tuple[Any, dict[str, str]] | None = None
        if endpoint.auth is not None:
            self._http.auth = (requests.auth.HTTPDigestAuth(*endpoint.auth) if endpoint.scheme == "digest"
                               else requests.auth.HTTPBasicAuth(*endpoint.auth))
        self._http.verify = endpoint.verify

    def close(self) -> None:
        self._http.close()

    def __enter__(self) -> "RemoteStore":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- HTTP ---------------------------------------------------------------------

    def _redact(self, text: str) -> str:
        """``text`` without the credentials (an error body may echo the request's headers)."""
        for secret in self.endpoint.secrets():
            text = text.replace(secret, "***")
        return text

    def _request(self, method: str, url: str, *, idempotent: bool = True, stream: bool = False,
                 **kwargs: Any) -> tuple[Any, bytes | None]:
        """One HTTP request and its answer's body (None when ``stream``), retried with backoff on
        transient failures; raises RemoteError.

        A request that is not ``idempotent`` (it writes) is sent again only when the endpoint
        cannot have carried it out: no connection was made, or it answered 429 or 503. No request
        is sent again after the endpoint kept silent for the whole timeout."""
        import requests

        delay = 0.5
        timeout = self.endpoint.timeout
        for attempt in range(self.endpoint.retries + 1):
            retry = True
            try:
                # verify given here: requests lets REQUESTS_CA_BUNDLE override the session's value
                response = self._http.request(method, url, timeout=(min(CONNECT_TIMEOUT, timeout), timeout),
                                              verify=self.endpoint.verify, stream=True, **kwargs)
                content = None if stream and response.status_code < 400 else _content(response, timeout)
            except requests.Timeout as e:
                if not isinstance(e, requests.ConnectTimeout):
                    written = "" if idempotent else "; it may have been carried out"
                    raise RemoteError(f"{method} {_safe(url)} did not answer within {timeout:g} s (--timeout or "
                                      f"${TIMEOUT_ENV} sets the limit){written}") from None
                failure = f"{_safe(url)} does not answer (no connection within {min(CONNECT_TIMEOUT, timeout):g} s)"
            except requests.exceptions.SSLError as e:
                reason = str(e.args[0].reason if e.args and hasattr(e.args[0], "reason") else e)[:200]
                raise RemoteError(f"{_safe(url)}: TLS failed ({reason}); ${CA_ENV} names the CA file of a private "
                                  "PKI") from None
            except requests.ConnectionError as e:
                failure = f"{type(e).__name__}: {_safe(url)} does not answer"
                retry = idempotent or _nothing_sent(e)
            except requests.exceptions.ChunkedEncodingError:  # the connection broke during the answer
                failure = f"{_safe(url)} does not answer (the connection broke during its answer)"
                retry = idempotent
            except requests.RequestException as e:
                raise RemoteError(self._redact(f"{method} {_safe(url)} failed: {e}")) from None
            else:
                if response.status_code < 400:
                    self._server = self._server or _software(response.headers.get("Server", ""))
                    return response, content
                if self._digest_asked(response):  # the server named the scheme: sent again with Digest, once
                    return self._request(method, url, idempotent=idempotent, stream=stream, **kwargs)
                body = (content or b"")[:300].decode("utf-8", "replace").strip()
                failure = self._redact(f"{method} {_safe(url)} answered {response.status_code}: {body}")
                retry = response.status_code in _TRANSIENT and (idempotent or response.status_code in (429, 503))
            if not retry:
                raise RemoteError(failure)
            if attempt < self.endpoint.retries:
                time.sleep(delay)
                delay *= 2
        raise RemoteError(f"{failure} (after {self.endpoint.retries + 1} attempts)")

    def _digest_asked(self, response: Any) -> bool:
        """Whether a 401 asks for HTTP Digest where Basic was sent (:data:`AUTH_ENV` unset): then
        the session answers with Digest from now on (Virtuoso's authenticated endpoints)."""
        import requests

        challenge = response.headers.get("WWW-Authenticate", "").lower()
        if (response.status_code != 401 or self.endpoint.auth is None or self.endpoint.scheme
                or not challenge.startswith("digest") or isinstance(self._http.auth, requests.auth.HTTPDigestAuth)):
            return False
        self._http.auth = requests.auth.HTTPDigestAuth(*self.endpoint.auth)
        return True

    def _staged(self, graph: str | None = None, sparql: str = "", graphs: Iterable[Any] = ()) -> Any:
        """The in-memory store of a load staged in the client (:meth:`_replace_from_client`) when a
        request names one of its staging graphs -- as ``graph``, in ``sparql`` or among a query's
        dataset ``graphs`` -- else None (the request goes to the server)."""
        if self._local is None:
            return None
        local, staging = self._local
        names = set(staging.values())
        if graph in names or any(_value(g) in names for g in graphs) or any(n in sparql for n in names):
            return local
        return None

    def update(self, sparql: str) -> None:
        """One SPARQL Update request (one transaction in the store)."""
        if (local := self._staged(sparql=sparql)) is not None:
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
        is staged in the client and sent in one request (:meth:`_replace_from_client`); elsewhere
        it is staged in the store and swapped in by one SPARQL Update (:meth:`_replace_in_store`)."""
        refuse_strangers(graph, companions)
        self._drop_stale_staging()
        if _DATASET_POST.match(self.server or ""):
            self._replace_from_client(graph, chunks, before_commit, companions)
        else:
            self._replace_in_store(graph, chunks, before_commit, companions)

    def _staging_names(self, graph: str, companions: Sequence[str]) -> tuple[dict[str, str], Callable[[str], str]]:
        """Fresh staging names for ``graph`` and ``companions``, and the load's ``target``: it
        stages the vocabulary graph too when the load rewrites it (missing or stale), so a failed
        load leaves it as it was."""
        stamp = int(time.time())
        staging = {name: f"{STAGING}{stamp}:{uuid.uuid4().hex}" for name in (graph, *companions)}

        def target(name: str) -> str:
            if name == VOCABULARY_GRAPH and name not in staging:
                staging[name] = f"{STAGING}{stamp}:{uuid.uuid4().hex}"
            return staging[name]

        return staging, target

    def _replace_in_store(self, graph: str, chunks: Iterable[Chunk],
                          before_commit: Callable[[Callable[[str], str]], None] | None,
                          companions: Sequence[str]) -> None:
        """Upload into staging graphs of the store, then swap them in with one SPARQL Update request."""
        staging, target = self._staging_names(graph, companions)
        doubles: set[bytes] = set()
        try:
            for name, body in _batches(chunks, BATCH_BYTES):
                if name is None:
                    doubles.update(_DOUBLE.findall(body))
                self._post_graph(staging[name or graph], body)
            # on a probe graph: reading the staging graph's doubles back scans it (Virtuoso 7,
            # 10k instances: 1.2 server CPU-s, 5 s)
            self._probe_doubles(graph, doubles)
            if before_commit is not None:
                before_commit(target)
            self._swap(staging)
        except BaseException:
            self._drop_quietly(staging.values())
            raise
        self._drop_quietly(staging.values())

    def _swap(self, staging: dict[str, str]) -> None:
        """Replace each graph by its staging graph: one request, so one transaction. ADD (a copy)
        and then dropping the staging graph in a second request is MOVE's meaning; on Oxigraph
        0.5 it keeps the swap itself to a third of MOVE's time (measured: 700k quads, 21 s
        against 71 s)."""
        self.update(" ;\n".join(f"DROP SILENT GRAPH {ox.NamedNode(name)} ; ADD SILENT GRAPH <{tmp}> TO "
                                 f"{ox.NamedNode(name)}" for name, tmp in staging.items()))

    def _replace_from_client(self, graph: str, chunks: Iterable[Chunk],
                             before_commit: Callable[[Callable[[str], str]], None] | None,
                             companions: Sequence[str]) -> None:
        """Stage the load in an in-memory store of the client, then write it by one request.

        ``before_commit`` reads and writes the staging graphs (the dangling-reference check, the
        derived layer's queries and updates): every request of this store that names one goes
        to the in-memory store instead (:meth:`_staged`), so none of that reaches the server.
        The server is asked only whether it keeps the load's xsd:double values (a probe graph of
        them, :meth:`_probe_doubles`) and whether the graphs exist. Graphs that do not exist yet
        are written under their own names by one N-Quads POST (one transaction: a failure, a
        client killed mid-request or a server killed mid-load leaves nothing); a replacement by one
        SPARQL Update that drops the graphs and inserts the new ones (:meth:`_commit_from`). One
        document holds every graph, so a blank node the derived layer shares with the program stays
        one node (separate documents would split it; the in-memory store names blank nodes anew, so
        the program's text as the loader wrote it cannot go first).

        Measured (10k instances of a replicated real program, Oxigraph 0.5.13): the load staged in
        the store cost the server 19.8 CPU-s (the swap 8.7, dropping the staging graphs 5.1), a new
        program staged in the client 3.4; a replacement 24-31 against 11-16."""
        from stepnc_graph.store import GraphStore

        staging, target = self._staging_names(graph, companions)
        doubles: set[str] = set()

        def counted(chunks: Iterable[Chunk]) -> Iterator[Chunk]:
            for chunk in chunks:
                if type(chunk) is str:
                    doubles.update(_DOUBLE_TEXT.findall(chunk))
                yield chunk

        with GraphStore(None) as local:
            self._local = (local, staging)
            try:
                local._bulk_load(staging[graph], counted(chunks), target)
                if before_commit is not None:
                    before_commit(target)
            finally:
                self._local = None
            self._probe_doubles(graph, {d.encode() for d in doubles})
            self._commit_from(local, staging)

    def _commit_from(self, local: Any, staging: dict[str, str]) -> None:
        """Write the staged graphs of ``local`` into the server (see :meth:`_replace_from_client`).

        Graphs that do not exist yet: one N-Quads POST under their own names. A replacement: one
        SPARQL Update request that drops the graphs and inserts the new ones (``INSERT DATA``, a
        transaction), streamed. The main graph's triple count is read back: a server that
        answered but did not load is an error, never a load reported done."""
        existing = [name for name in staging if self.has_graph(name)]
        names = {tmp: name for name, tmp in staging.items()}
        main = next(iter(staging))
        try:
            if existing:
                drops = " ;\n".join(f"DROP SILENT GRAPH {ox.NamedNode(name)}" for name in staging)
                self._request("POST", self.endpoint.update_url, idempotent=False,
                              data=_NQuadsBody(local, names, update=drops),
                              headers={"Content-Type": "application/sparql-update"})
            else:
                self._post_dataset(_NQuadsBody(local, names))
        except BaseException:
            if not existing:
                self._drop_quietly(names.values())
            raise
        if (got := self.count(main)) != (want := local.count(staging[main])):
            if not existing:
                self._drop_quietly(names.values())
            raise RemoteError(f"{self.endpoint} answered the load of graph {main} ({want} triples) but holds {got} of "
                              "them: it was not loaded")

    def _post_dataset(self, body: "_NQuadsBody") -> None:
        self._request("POST", self.endpoint.store_url, idempotent=False, data=body,
                      headers={"Content-Type": _NQUADS})

    def _probe_doubles(self, graph: str, sent: set[bytes]) -> None:
        """:meth:`_check_doubles` on a probe graph holding one triple per distinct xsd:double value
        the load writes (a staging graph, dropped after): the store is not changed when refused."""
        if not sent:
            return
        probe = f"{STAGING}{int(time.time())}:{uuid.uuid4().hex}"
        subject = ox.NamedNode(probe)
        lines = "".join(f"{subject} <{probe}#v{i}> \"{text.decode()}\"^^<{_XSD_DOUBLE}> .\n"
                        for i, text in enumerate(sorted(sent)))
        try:
            self._post_graph(probe, lines.encode("utf-8"))
            self._check_doubles(graph, probe, sent)
        finally:
            self._drop_quietly([probe])

    def _check_doubles(self, graph: str, staged: str, sent: set[bytes]) -> None:
        """RemoteError unless the store gives back every xsd:double value written into ``staged``
        (distinct values, compared as numbers: a store may write its own lexical form).

        Some stores keep a double but answer it rounded, in every results format (Virtuoso 7: six
        significant digits, so 0.123456789 reads back as 0.123457); every later query and export
        would then hand back changed data. The load is refused before anything is swapped in."""
        if not sent:
            return
        rows = self.query(f"SELECT DISTINCT ?o WHERE {{ GRAPH <{staged}> {{ ?s ?p ?o FILTER(isLiteral(?o) && "
                          f"datatype(?o) = <{_XSD_DOUBLE}>) }} }}")
        back = {_number(row[0].value) for row in rows if isinstance(row[0], ox.Literal)}
        lost = sorted((text.decode() for text in sent if _number(text.decode()) not in back), key=len)
        if lost:
            near = [row[0].value for row in self.query(
                f"SELECT ?o WHERE {{ GRAPH <{staged}> {{ ?s ?p ?o FILTER(isLiteral(?o) && datatype(?o) = "
                f"<{_XSD_DOUBLE}> && ?o = {ox.Literal(lost[-1], datatype=ox.NamedNode(_XSD_DOUBLE))}) }} }} LIMIT 1")]
            shown = f"{lost[-1]} reads back as {near[0]}" if near else f"{lost[-1]} does not read back"
            raise RemoteError(f"{self.endpoint} does not give back the xsd:double values written ({shown}; "
                              f"{len(lost)} of the {len(sent)} distinct values of <{graph}> differ): every query and "
                              "export would hand back changed data, so it was not loaded (the store was not changed)")

    def _drop_quietly(self, graphs: Iterable[str]) -> None:
        """Drop staging graphs; if the server is gone, a later load drops them once stale."""
        try:
            self.update(" ; ".join(f"DROP SILENT GRAPH <{g}>" for g in graphs))
        except RemoteError:
            pass

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
            return
        for _, body in _batches([text], BATCH_BYTES):
            self._post_graph(graph, body)

    def add_turtle(self, graph: str, text: str) -> None:
        if (local := self._staged(graph)) is not None:
            local.add_turtle(graph, text)
            return
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

    def quads(self, graph: str | None = None) -> Iterator[ox.Quad]:
        """A graph's quads (Graph Store Protocol GET); every graph's for None."""
        if graph is not None and (local := self._staged(graph)) is not None:
            yield from local.quads(graph)
            return
        for name in [graph] if graph else self.all_graphs():
            assert name is not None
            response, _ = self._request("GET", self.endpoint.store_url, params={"graph": name},
                                        headers={"Accept": _NTRIPLES}, stream=True)
            media_type = response.headers.get("Content-Type", "").split(";")[0].strip().lower()
            if media_type != _NTRIPLES:
                response.close()
                raise RemoteError(f"{self.endpoint.store_url} answered {_kind(media_type)} for graph {name}, "
                                  f"where N-Triples ({_NTRIPLES}) were expected")
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
        keeps the order of its values is known once it has answered (:data:`_UNORDERED_CONCAT`)."""
        return Capabilities(persistent=True, blank_node_writes=False, local_reads=False, compactable=False,
                            ordered_group_concat=_UNORDERED_CONCAT.match(self.server or "") is None)

    @property
    def server(self) -> str | None:
        """The endpoint's ``Server`` header, from its first answer that named one."""
        return self._server

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


def _content(response: Any, timeout: float) -> bytes:
    """The whole body of a streamed ``response``, read within ``timeout`` seconds however slowly
    it comes (requests' own timeout bounds each read, not the whole)."""
    import requests

    deadline = time.monotonic() + timeout
    parts = []
    with response:
        for part in response.iter_content(1 << 16):
            parts.append(part)
            if time.monotonic() > deadline:
                raise requests.ReadTimeout("the answer did not end in time")
    return b"".join(parts)


def _nothing_sent(error: Exception) -> bool:
    """Whether a connection error happened before the request was sent (no connection made)."""
    from urllib3.exceptions import NewConnectionError

    reason = getattr(error.args[0], "reason", None) if error.args else None
    return isinstance(reason, NewConnectionError) or "NewConnectionError" in str(error)


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
