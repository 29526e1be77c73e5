"""How a remote store writes a load, atomically (:meth:`stepnc_graph.store.remote.RemoteStore.replace_graph`).

On a server that loads an N-Quads POST in one transaction (:data:`stepnc_graph.store.remote._DATASET_POST`)
the load is staged in the client, in an in-memory store -- the derived layer's queries and updates
run there -- and the server gets it in one request (:func:`replace_from_client`). Elsewhere it is
staged in graphs of the store and swapped in by one SPARQL Update (:func:`replace_in_store`)."""

from __future__ import annotations

import queue
import re
import threading
import time
import uuid
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import IO, TYPE_CHECKING, Any, cast

import pyoxigraph as ox

from stepnc_graph.core.naming import STAGING, VOCABULARY_GRAPH
from stepnc_graph.store.answers import _DOUBLE, _XSD_DOUBLE, RemoteError, _number
from stepnc_graph.store.contract import Chunk
from stepnc_graph.store.contract import Companion, Joint
from stepnc_graph.store.remote_difference import (
    OldVersion,
    new_load_id,
    replace_by_difference,
    token_graph,
    token_line,
)

if TYPE_CHECKING:
    from stepnc_graph.store.remote import RemoteStore

#: bytes of N-Triples per Graph Store Protocol request of a load staged in the store: small, so the server
#: starts parsing soon after the load starts, while the client maps the rest (Virtuoso 7.2, replicated 10k,
#: in-process, medians of 3 at load average 3.4-4: a new load 4.4 s wall with 1 MB, 5.2 s with 8 MB)
BATCH_BYTES = 1 << 20

#: the lexical form of each xsd:double literal in N-Triples text (see answers._DOUBLE)
_DOUBLE_TEXT = re.compile(_DOUBLE.pattern.decode())


def _batches(chunks: Iterable[Chunk], size: int) -> Iterator[tuple[str | None, bytes]]:
    """The chunks' text in UTF-8 batches of about ``size`` bytes (chunks end at triple boundaries),
    each with its graph: None for the main graph, a companion's name for its chunks (sent alone)."""
    pending: list[bytes] = []
    used = 0
    for chunk in chunks:
        if isinstance(chunk, Joint):  # the text alone: the load copies the lines in the store (see Joint)
            chunk = chunk.text
        elif isinstance(chunk, Companion):
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


def _staging_names(store: "RemoteStore", graph: str, companions: Sequence[str]) -> tuple[dict[str, str], Callable[[str], str]]:
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

def replace_in_store(store: "RemoteStore", graph: str, chunks: Iterable[Chunk],
                      before_commit: Callable[[Callable[[str], str]], None] | None,
                      companions: Sequence[str]) -> None:
    """Upload into staging graphs of the store, then swap them in with one SPARQL Update request.

    The batches go out from a thread of their own (:class:`_Uploader`) while the client maps the
    next, and the client keeps a copy of the program's text in an in-memory store meanwhile:
    ``before_commit``'s reads of the program (the reference check, the derived layer's walks)
    go there (:attr:`RemoteStore._copy`), its writes to the store. Those reads were a dozen
    SELECTs of the staging graph, one after the other, while the client waited (Virtuoso 7.2, a
    replicated 10k-instance program: 2.2 s wall, 1.6 server CPU-s of a 7.2 s load); the copy
    costs the client's memory what the in-memory store holds (about what ``load --memory`` does)."""
    from stepnc_graph.store import GraphStore

    staging, target = _staging_names(store, graph, companions)
    doubles: set[bytes] = set()
    try:
        with GraphStore(None) as copy:
            with _Uploader(store) as uploader:
                copy._bulk_load(staging[graph], _sent(chunks, uploader, staging, graph, doubles))
            # on a probe graph: reading the staging graph's doubles back scans it (Virtuoso 7,
            # 10k instances: 1.2 server CPU-s, 5 s)
            _probe_doubles(store, graph, doubles)
            if before_commit is not None:
                store._copy = (copy, staging[graph])
                try:
                    before_commit(target)
                finally:
                    store._copy = None
        _swap(store, staging)
    except BaseException:
        store._drop_quietly(staging.values())
        raise
    store._drop_quietly(staging.values())


def _sent(chunks: Iterable[Chunk], uploader: "_Uploader", staging: dict[str, str], graph: str,
          doubles: set[bytes]) -> Iterator[str]:
    """The main graph's text of ``chunks`` (for the client's copy), each batch of about
    :data:`BATCH_BYTES` handed to ``uploader`` for ``graph``'s staging graph as it fills, a
    companion's chunk for its own; the xsd:double values of the main graph go into ``doubles``."""
    pending: list[bytes] = []
    used = 0

    def flush() -> None:
        nonlocal used
        body = b"".join(pending)
        doubles.update(_DOUBLE.findall(body))
        uploader.send(staging[graph], body)
        pending.clear()
        used = 0

    for chunk in chunks:
        if isinstance(chunk, Joint):  # the text alone: the load copies the lines in the store (see Joint)
            chunk = chunk.text
        elif isinstance(chunk, Companion):
            uploader.send(staging[chunk.graph], chunk.text.encode("utf-8"))
            continue
        data = chunk.encode("utf-8")
        pending.append(data)
        used += len(data)
        if used >= BATCH_BYTES:
            flush()
        yield chunk
    if pending:
        flush()


class _Uploader:
    """Graph Store POSTs on a thread of their own, in the order given, at most two waiting: the
    server parses one batch while the client maps the next. The first failure is raised to the
    sender (at its next :meth:`send`, or on leaving the block); leaving the block waits for every
    request given, or, on an error, for the one under way only."""

    def __init__(self, store: "RemoteStore") -> None:
        self.store = store
        self.work: queue.Queue[tuple[str, bytes] | None] = queue.Queue(maxsize=2)
        self.error: BaseException | None = None
        self.stop, self.done = threading.Event(), threading.Event()
        self.thread = threading.Thread(target=self._run, name="stepnc-graph upload", daemon=True)

    def __enter__(self) -> "_Uploader":
        self.thread.start()
        return self

    def __exit__(self, kind: type[BaseException] | None, *rest: object) -> None:
        if kind is not None:
            self.stop.set()
        try:
            self._finish()
        except BaseException:  # interrupted while waiting (Ctrl-C): send nothing more, and wait for
            self.stop.set()   # the request under way, so the caller's drop of the staging graphs
            self._finish()    # comes after every POST into them
            raise
        if kind is None and self.error is not None:
            raise self.error

    def _finish(self) -> None:
        """Wait until the thread sent what it was given (or skipped it, once stopped). Waited for on
        an event the thread sets, not by ``join``: a ``join`` interrupted by Ctrl-C may leave the
        thread marked as ended while it still sends (CPython 3.11)."""
        self._put(None)
        self.done.wait()

    def send(self, graph: str, body: bytes) -> None:
        """POST ``body`` into ``graph`` once those before it went."""
        if self.error is not None:
            raise self.error
        self._put((graph, body))

    def _put(self, item: tuple[str, bytes] | None) -> None:
        while not self.done.is_set():
            try:
                self.work.put(item, timeout=0.1)
                return
            except queue.Full:
                if self.error is not None and item is not None:
                    raise self.error from None

    def _run(self) -> None:
        try:
            while (item := self.work.get()) is not None:
                if self.stop.is_set() or self.error is not None:
                    continue
                try:
                    self.store._post_graph(*item)
                except BaseException as exc:  # noqa: BLE001 -- raised to the sender
                    self.error = exc
        finally:
            self.done.set()

def _swap(store: "RemoteStore", staging: dict[str, str]) -> None:
    """Replace each graph by its staging graph: one request, so one transaction. ADD (a copy)
    and then dropping the staging graph in a second request is MOVE's meaning; on Oxigraph
    0.5 it keeps the swap itself to a third of MOVE's time (measured: 700k quads, 21 s
    against 71 s)."""
    store.update(" ;\n".join(f"DROP SILENT GRAPH {ox.NamedNode(name)} ; ADD SILENT GRAPH <{tmp}> TO "
                             f"{ox.NamedNode(name)}" for name, tmp in staging.items()))

def _probe_doubles(store: "RemoteStore", graph: str, sent: set[bytes]) -> None:
    """:func:`_check_doubles` on a probe graph holding one triple per distinct xsd:double value
    the load writes (a staging graph, dropped after): the store is not changed when refused."""
    if not sent:
        return
    probe = f"{STAGING}{int(time.time())}:{uuid.uuid4().hex}"
    subject = ox.NamedNode(probe)
    lines = "".join(f"{subject} <{probe}#v{i}> \"{text.decode()}\"^^<{_XSD_DOUBLE}> .\n"
                    for i, text in enumerate(sorted(sent)))
    try:
        store._post_graph(probe, lines.encode("utf-8"))
        _check_doubles(store, graph, probe, sent)
    finally:
        store._drop_quietly([probe])

def _check_doubles(store: "RemoteStore", graph: str, staged: str, sent: set[bytes]) -> None:
    """RemoteError unless the store gives back every xsd:double value written into ``staged``
    (distinct values, compared as numbers: a store may write its own lexical form).

    Some stores keep a double but answer it rounded, in every results format (Virtuoso 7: six
    significant digits, so 0.123456789 reads back as 0.123457); every later query and export
    would then hand back changed data. The load is refused before anything is swapped in."""
    if not sent:
        return
    rows = store.query(f"SELECT DISTINCT ?o WHERE {{ GRAPH <{staged}> {{ ?s ?p ?o FILTER(isLiteral(?o) && "
                      f"datatype(?o) = <{_XSD_DOUBLE}>) }} }}")
    back = {_number(row[0].value) for row in rows if isinstance(row[0], ox.Literal)}
    lost = sorted((text.decode() for text in sent if _number(text.decode()) not in back), key=len)
    if lost:
        near = [row[0].value for row in store.query(
            f"SELECT ?o WHERE {{ GRAPH <{staged}> {{ ?s ?p ?o FILTER(isLiteral(?o) && datatype(?o) = "
            f"<{_XSD_DOUBLE}> && ?o = {ox.Literal(lost[-1], datatype=ox.NamedNode(_XSD_DOUBLE))}) }} }} LIMIT 1")]
        shown = f"{lost[-1]} reads back as {near[0]}" if near else f"{lost[-1]} does not read back"
        raise RemoteError(f"{store.endpoint} does not give back the xsd:double values written ({shown}; "
                          f"{len(lost)} of the {len(sent)} distinct values of <{graph}> differ): every query and "
                          "export would hand back changed data, so it was not loaded (the store was not changed)")


def replace_from_client(store: "RemoteStore", graph: str, chunks: Iterable[Chunk],
                         before_commit: Callable[[Callable[[str], str]], None] | None,
                         companions: Sequence[str]) -> None:
    """Stage the load in an in-memory store of the client, then write it by one request.

    ``before_commit`` reads and writes the staging graphs (the dangling-reference check, the
    derived layer's queries and updates): every request of this store that names one goes
    to the in-memory store instead (:meth:`RemoteStore._staged`), so none of that reaches the server.
    The server is asked only whether it keeps the load's xsd:double values (a probe graph of
    them, :func:`_probe_doubles`) and whether the graphs exist. Graphs that do not exist yet
    are written under their own names by one N-Quads POST (atomic: a failure, a client killed
    mid-request or a server killed mid-load leaves nothing; by the server's bulk loader where
    that is atomic too, :func:`~stepnc_graph.store.remote.atomic_bulk_post`); a replacement by one
    SPARQL Update of what changed since the old version, read meanwhile (:class:`OldVersion`,
    :func:`replace_by_difference`), or else one that drops the graphs and inserts the new ones
    (:func:`_commit_from`). Every load records its id in the program's :func:`token_graph`. One
    document holds every graph, so a blank node the derived layer shares with the program stays
    one node (separate documents would split it; the in-memory store names blank nodes anew, so
    the program's text as the loader wrote it cannot go first).

    Measured (10k instances of a replicated real program, Oxigraph 0.5.13): the load staged in
    the store cost the server 19.8 CPU-s (the swap 8.7, dropping the staging graphs 5.1), a new
    program staged in the client 3.4 (by the bulk loader: 1.4-2.8); a replacement 24-31 against
    11-16."""
    from stepnc_graph.store import GraphStore

    staging, target = _staging_names(store, graph, [*companions, token_graph(graph)])
    doubles: set[str] = set()

    def counted(chunks: Iterable[Chunk]) -> Iterator[Chunk]:
        for chunk in chunks:
            if isinstance(chunk, Joint):  # the text alone: the load copies the lines (see Joint)
                chunk = chunk.text
            if type(chunk) is str:
                doubles.update(_DOUBLE_TEXT.findall(chunk))
            yield chunk

    before = OldVersion(store, [graph, *companions, token_graph(graph)])  # read while the load is staged
    with GraphStore(None) as local:
        store._local = (local, staging)
        try:
            local._bulk_load(staging[graph], counted(chunks), target)
            if before_commit is not None:
                before_commit(target)
            local.add_ntriples(staging[token_graph(graph)], token_line(graph, new_load_id()))
        finally:
            store._local = None
        _probe_doubles(store, graph, {d.encode() for d in doubles})
        _commit_from(store, local, staging, before)

#: quads of a replacement sent as one SPARQL Update at most: Oxigraph's server takes update bodies
#: of 128 MiB at most (``SPARQL body payloads are limited to 134217728 bytes``), and a replicated
#: real program takes ~158 bytes a quad there (a 100k-instance one's replacement: ~220 MB). A larger
#: replacement goes into staging graphs by one N-Quads POST and is swapped in (:func:`_swap`); a
#: replacement by difference of more lines is written so too
UPDATE_QUADS = 300_000


def _commit_from(store: "RemoteStore", local: Any, staging: dict[str, str], before: OldVersion) -> None:
    """Write the staged graphs of ``local`` into the server (see :func:`replace_from_client`).

    Graphs that do not exist yet: one N-Quads POST under their own names. A replacement: by
    difference (:func:`replace_by_difference`), else whole (:func:`_replace`); ``last_removal``
    says which, and why whole. The main graph's triple count is read back: a server that answered but did
    not load is an error, never a load reported done.

    A POST adds to what a graph holds, so two clients creating the same graph at the same moment
    (both found it missing) would leave both loads in it, mixed. A count other than the one
    written after a new graph's POST is therefore answered by one replacement, a single
    transaction: the graph then holds this load alone, as if the two had run one after the
    other (the last one wins, as for replacements), and never a mix of them."""
    existing = [name for name in staging if store.has_graph(name)]
    names = {tmp: name for name, tmp in staging.items()}
    main = next(iter(staging))
    want = local.count(staging[main])
    got: int | None = None  # the main graph's count read back, once it is this load's last write
    if existing:
        store.last_removal = "difference"
        if (whole := replace_by_difference(store, local, staging, UPDATE_QUADS, before)) is not None:
            store.last_removal = f"whole: {whole}"
            _replace(store, local, staging)
    else:
        try:
            store._post_dataset(_NQuadsBody(local, names))
        except BaseException:
            store._drop_quietly(names.values())
            raise
        if (got := store.count(main)) != want:
            _replace(store, local, staging)
            got = None
    if (got := store.count(main) if got is None else got) != want:
        left = "" if got == 0 else " (what it holds now is not this load: `unload` it or load the file again)"
        raise RemoteError(f"{store.endpoint} answered the load of graph {main} ({want} triples) but holds {got} of "
                          f"them: it was not loaded{left}")


def _replace(store: "RemoteStore", local: Any, staging: dict[str, str]) -> None:
    """Replace the graphs of ``staging`` by those of ``local`` in one transaction: one SPARQL
    Update request that drops them and inserts the new ones (``INSERT DATA``), streamed; above
    :data:`UPDATE_QUADS`, one N-Quads POST into fresh staging graphs swapped in by one SPARQL
    Update (:func:`_swap`)."""
    if sum(local.count(tmp) for tmp in staging.values()) > UPDATE_QUADS:
        stamp = f"{STAGING}{int(time.time())}:"
        swapped = {tmp: stamp + uuid.uuid4().hex for tmp in staging.values()}
        try:
            store._post_dataset(_NQuadsBody(local, swapped))
            _swap(store, {name: swapped[tmp] for name, tmp in staging.items()})
        finally:
            store._drop_quietly(swapped.values())
        return
    drops = " ;\n".join(f"DROP SILENT GRAPH {ox.NamedNode(name)}" for name in staging)
    store._request("POST", store.endpoint.update_url, idempotent=False,
                   data=_NQuadsBody(local, {tmp: name for name, tmp in staging.items()}, update=drops),
                   headers={"Content-Type": "application/sparql-update"})


class _NQuadsBody:
    """The graphs of an in-memory store as one N-Quads request body, renamed by ``names`` (staged
    name -> name in the server), made in pieces while it is sent (chunked transfer: no copy of
    the whole document in memory). Iterable again from the start: a request sent again (no
    connection was made the first time) sends the whole document again, never a spent one.

    Each graph's text is Oxigraph's own N-Triples dump of it (:func:`_dumped`): no quad becomes a
    Python object (measured, a replicated 20k-instance program's 58 MB body: 0.43 CPU-s, where
    reading its quads into Python and serializing them took 0.82)."""

    #: bytes of text a piece holds at least (a piece ends at a line's end)
    piece = 1 << 20

    def __init__(self, local: Any, names: dict[str, str], update: str | None = None) -> None:
        self.local, self.names, self.update = local, names, update

    def __iter__(self) -> Iterator[bytes]:
        if self.update is not None:
            yield self.update.encode("utf-8") + b" ;\nINSERT DATA {\n"
        for staged, name in self.names.items():
            into = ox.NamedNode(name)
            if self.update is not None:
                yield f"GRAPH {into} {{\n".encode()
                yield from _dumped(self.local.oxigraph, staged, self.piece)
                yield b"}\n"
            else:  # N-Quads: each N-Triples line with the graph before its final " ."
                tail = f" {into} .\n".encode()
                yield from (text.replace(b" .\n", tail) for text in _dumped(self.local.oxigraph, staged, self.piece))
        if self.update is not None:
            yield b"}\n"


class _Stopped(Exception):
    """The reader of a dump stopped reading (its request failed, or it was closed)."""


def _dumped(store: ox.Store, graph: str, piece: int) -> Iterator[bytes]:
    """``graph``'s N-Triples as Oxigraph dumps them, in pieces of at least ``piece`` bytes that end
    at a line's end. The dump runs on a thread and writes into a bounded queue, so the text is
    made while the caller sends it; a caller that stops reading stops the dump (no thread is left
    behind), and an error of the dump is raised to the caller."""
    parts: queue.Queue[bytes | BaseException | None] = queue.Queue(maxsize=16)
    stop = threading.Event()
    pending: list[bytes] = []

    def put(item: bytes | BaseException | None) -> None:
        while True:
            if stop.is_set():
                raise _Stopped
            try:
                parts.put(item, timeout=0.1)
                return
            except queue.Full:
                continue

    class Pipe:
        size = 0

        def write(self, data: bytes) -> int:
            pending.append(bytes(data))
            self.size += len(data)
            if self.size >= piece:
                put(b"".join(pending))
                pending.clear()
                self.size = 0
            return len(data)

        def flush(self) -> None:
            """Nothing: what was written is queued already (the dump calls it at its end)."""

    def dump() -> None:
        try:
            store.dump(cast("IO[bytes]", Pipe()), format=ox.RdfFormat.N_TRIPLES, from_graph=ox.NamedNode(graph))
            put(b"".join(pending))
            put(None)
        except _Stopped:
            pass
        except BaseException as exc:  # noqa: BLE001 -- raised to the reader
            try:
                put(exc)
            except _Stopped:
                pass

    thread = threading.Thread(target=dump, name="stepnc-graph N-Triples dump", daemon=True)
    thread.start()
    rest = b""
    try:
        while (part := parts.get()) is not None:
            if isinstance(part, BaseException):
                raise part
            text = rest + part
            cut = text.rfind(b"\n") + 1
            rest = text[cut:]
            if cut:
                yield text[:cut]
        if rest:
            yield rest
    finally:
        stop.set()
        thread.join()
