"""Threaded bulk loading: a load's chunks streamed into the embedded store by one bulk loader per core.

One ``bulk_load`` call ingests a named graph on disk with one core, and two concurrent calls on
halves of the data nearly double that (the figures are in docs/loading.md, "The store's tuning,
measured"). So the producer (the caller's thread: parse and map) fills a bounded hand-off and
:data:`~stepnc_graph.store.tuning.LOAD_THREADS` threads each run a streaming ``bulk_load`` over it
(pyoxigraph releases the GIL while loading; an in-memory store is fed differently, see
:data:`~stepnc_graph.store.tuning.MEMORY_BATCH_CHARS`). Chunks end at instance boundaries and
blank-node labels are unique per load, so every thread's document is self-contained; a
:class:`~stepnc_graph.store.contract.Joint` chunk's companion lines travel in the same document as
the text whose blank nodes they name, as N-Quads naming their graph.
"""

from __future__ import annotations

import io
import threading
from collections.abc import Callable, Iterable, Iterator
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.store import tuning
from stepnc_graph.store.batches import ChunkStream
from stepnc_graph.store.contract import Chunk, Joint
from stepnc_graph.store.handoff import Handoff

if TYPE_CHECKING:
    from stepnc_graph.store.embedded import GraphStore

#: what the producer hands a worker: text, and whether it is N-Quads (lines of a companion graph
#: naming it) rather than N-Triples (the main graph's alone), see BulkLoad._item
Item = tuple[bytes, bool]


class BulkLoad:
    """One bulk load of ``chunks`` into ``graph`` of ``store``; a :class:`Companion` chunk's lines
    go into ``target(its graph)`` in the same calls. The first error of any thread aborts the hand-off, which
    stops the producer and every worker (see :mod:`stepnc_graph.store.handoff`).

    No attribute or local name holds the database (workers read ``store._db`` at each call): a
    failure's traceback keeps these frames alive, and the rollback must be able to close it."""

    def __init__(self, store: GraphStore, graph: str, target: Callable[[str], str], in_memory: bool) -> None:
        self.store, self.main, self.target, self.in_memory = store, ox.NamedNode(graph), target, in_memory
        self.threads_n = 1 if in_memory else tuning.LOAD_THREADS  # see tuning.MEMORY_BATCH_CHARS
        self.work: Handoff[Item] = Handoff(2 * self.threads_n)
        self.errors: list[BaseException] = []

    def run(self, graph: str, chunks: Iterable[Chunk]) -> None:
        """Produce the chunks (encoded once: also for the store's tee) while the workers load them."""
        threads = [threading.Thread(target=self._worker, daemon=True) for _ in range(self.threads_n)]
        for t in threads:
            t.start()
        try:
            self._produce(graph, chunks)
        except BaseException:
            self.work.abort()
            raise
        finally:
            self.work.close()
            for t in threads:
                t.join()
        if self.errors:
            raise self.errors[0]

    def _produce(self, graph: str, chunks: Iterable[Chunk]) -> None:
        for chunk in chunks:
            if not self.work.put(self._item(graph, chunk)):
                return  # a worker failed

    def _item(self, graph: str, chunk: Chunk) -> Item:
        """What a worker loads for ``chunk``, encoded once (also for the store's tee): the main
        graph's text as it is (N-Triples is N-Quads in the default graph, which is the main
        graph), a companion's lines as N-Quads naming their graph -- after the text whose blank nodes
        they name, for a :class:`Joint` chunk, so the two parts are one document. So a load is a
        few bulk calls, whatever its companions: each call is one more set of table files that
        RocksDB compacts later (see docs/loading.md, "The store's tuning, measured")."""
        if isinstance(chunk, str):
            return self._teed(graph, chunk), False
        if isinstance(chunk, Joint):
            return self._teed(graph, chunk.text) + self._named(chunk.graph, chunk.lines), True
        return self._named(chunk.graph, chunk.text), True

    def _teed(self, graph: str, text: str) -> bytes:
        """N-Triples ``text`` of ``graph`` encoded, and handed to the store's tee as such."""
        data = text.encode("utf-8")
        if self.store._tee is not None:
            self.store._tee.write_bytes(graph, data)
        return data

    def _named(self, graph: str, text: str) -> bytes:
        """N-Triples ``text`` of the companion ``graph`` (teed as such) as N-Quads of where that
        graph is written now."""
        # each N-Triples line ends " .\n" (a line break inside a literal is escaped)
        return self._teed(graph, text).replace(b" .\n", f" {ox.NamedNode(self.target(graph))} .\n".encode("utf-8"))

    def _worker(self) -> None:
        try:
            ended = False
            while not ended:
                large: list[Item] = []
                ended = self._load_batch(large)
                for data, quads in large:
                    self.store._db.bulk_load(data, _format(quads), to_graph=self.main, lenient=True)
                if self.work.aborted:  # another thread failed: what this one loaded is rolled back
                    return
        except BaseException as exc:  # noqa: BLE001 -- raised by the producer thread
            self.errors.append(exc)
            self.work.abort()

    def _load_batch(self, large: list[Item]) -> bool:
        """One bulk_load call of chunks; True when the hand-off has ended."""
        ended: list[bool] = []
        quads: list[bool] = []
        if self.in_memory:
            data = b"".join(self._pull(tuning.MEMORY_BATCH_CHARS, large, ended, quads))
            if data:
                self.store._db.bulk_load(data, _format(any(quads)), to_graph=self.main, lenient=True)
        else:  # the format is chosen before the first chunk is read: streamed, both read alike
            stream = io.BufferedReader(ChunkStream(self._pull(tuning.BATCH_CHARS, large, ended, quads)), 1 << 20)
            self.store._db.bulk_load(stream, ox.RdfFormat.N_QUADS, to_graph=self.main, lenient=True)
        return bool(ended)

    def _pull(self, budget: int, large: list[Item], ended: list[bool], quads: list[bool]) -> Iterator[bytes]:
        """Chunks for one streaming bulk_load call: at most ``budget`` characters' worth; a chunk
        too large for the streaming reader ends the call and goes to ``large``; the hand-off's end
        is noted in ``ended``, whether each chunk is N-Quads in ``quads``."""
        used = 0
        while used < budget:
            item = self.work.get()
            if item is None:
                ended.append(True)
                return
            if len(item[0]) > tuning.DIRECT_CHARS:
                large.append(item)
                return
            used += len(item[0])
            quads.append(item[1])
            yield item[0]


def _format(quads: bool) -> ox.RdfFormat:
    """How to read text from bytes: N-Triples where it is (Oxigraph reads it faster from bytes:
    an in-memory load of a 100k-instance program's graph, ``validate FILE``'s, took 1.11x the CPU
    as N-Quads), else N-Quads."""
    return ox.RdfFormat.N_QUADS if quads else ox.RdfFormat.N_TRIPLES
