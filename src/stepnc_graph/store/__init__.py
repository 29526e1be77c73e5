"""The graph store: an embedded Oxigraph database, on disk by default.

Layout of a store directory (format 2)::

    DIR/stepnc-graph-store.json   marker (format version)
    DIR/write.lock                the writer holds an exclusive lock on it (and writes its pid there)
    DIR/CURRENT                   the name of the published generation, e.g. "g000007"
    DIR/g000007/                  a published generation: an Oxigraph checkpoint nobody writes to
    DIR/g000007.lock              readers hold a shared lock on it while they read that generation
    DIR/work/                     the writer's read-write database
    DIR/work.dirty                present while work/ may differ from the published generation
    DIR/deleted-quads             quads deleted since work/ was last compacted (see store/tuning.py)
    DIR/kept/                     each graph's last loaded text, compressed, and its index
                                  (stepnc_graph.store.kept): a replacement's old version
    DIR/rebuild/, DIR/difference/ a write's scratch (a database being rebuilt, a replacement's texts)

**One writer, many readers.** RocksDB lets one process open a database for
writing, and a read-only opening of a database another process writes to is
undefined behaviour (measured here: ``Corruption ... 000009.sst: No such file``
as soon as the writer compacts). So readers never open ``work/``: they open the
published generation read-only, which is a checkpoint (hard links, taken in
milliseconds) that no one writes to and that is not deleted while a reader
holds its lock. A reader therefore sees the state before a running load, and
never blocks it. A second writer fails at once with :class:`StoreBusy` naming
the holder, or waits (``wait=True``); only the process holding the writer's lock
ever recovers anything.

**Atomic, kill -9 safe writes.** A write marks ``work.dirty``, changes
``work/`` (Oxigraph's bulk loader is fast but not transactional), then
publishes a new generation: a checkpoint of ``work/`` renamed into place and
named in ``CURRENT`` (an atomic rename). A failure, or a writer killed at any
point, leaves ``CURRENT`` naming the previous generation; the next writer sees
``work.dirty`` and rebuilds ``work/`` from that generation (hard links again).

**Unload and replace, as close to the cost of a load as Oxigraph allows.** Oxigraph deletes
quad by quad in transactions, which costs more than a bulk load of the same quads (the figures
are in docs/loading.md, "The store's tuning, measured"). So removing a graph either deletes its
quads in bounded batches, or -- when the graph is a large part of the store -- rebuilds the
database from the other graphs (:mod:`.removal`), whichever costs less; deleted quads keep their
disk space until a compaction, which an unload runs once enough was deleted
(:data:`~stepnc_graph.store.tuning.COMPACT_AT`). A replacement writes only what changed
(:mod:`.replacement`), comparing the new version as the load wrote it with the old one as its
load wrote it (:mod:`.kept`). :meth:`GraphStore.compact` rebuilds the database, giving back the
strings that only removed quads used.

An in-memory store (:class:`MemoryStore`, ``path=None``) loads a new graph in place
(dropping it on failure) and a replacement into staging graphs moved into place in one SPARQL
Update transaction. The store directory is chosen by ``--store DIR``, else
``$STEPNC_GRAPH_STORE``, else ``./.stepnc-graph``. The classes are in :mod:`.embedded`; this
module names what callers import.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from stepnc_graph.store.contract import Capabilities, Chunk, Companion, Joint, Maintenance, Store
from stepnc_graph.store.embedded import GraphStore, MemoryStore
from stepnc_graph.store.errors import StoreBusy, StoreError, StoreWriteError
from stepnc_graph.store.files import DEFAULT_STORE, FORMAT_VERSION, STORE_ENV, default_store_path, directory_bytes
from stepnc_graph.store.locks import Writer

__all__ = ["Capabilities", "Chunk", "Companion", "GraphStore", "Joint", "Maintenance", "MemoryStore", "Store",
           "StoreBusy", "StoreError", "StoreWriteError", "Writer", "DEFAULT_STORE", "STORE_ENV", "FORMAT_VERSION",
           "default_store_path", "directory_bytes", "open_store"]


def open_store(path: str | Path | None = None, memory: bool = False, *, readonly: bool | None = None,
               create: bool | None = None, wait: bool | float = False,
               on_wait: Callable[[Writer], None] | None = None) -> GraphStore:
    """The on-disk store at ``path`` (default: ``$STEPNC_GRAPH_STORE`` or ``./.stepnc-graph``), or an in-memory one.

    By default the store reads the last published state without blocking anyone, and takes the
    writer's lock at its first write (a load, an unload, a link, a compaction): a notebook that
    only reads never stops a ``stepnc-graph load``. The write then reads the newest published
    state; if another process is writing, it raises :class:`StoreBusy` (or waits with ``wait``)
    and the store can still be read. Once it has written, it holds the lock until it is closed
    (use ``with``). ``readonly=False`` takes the lock at once (as the CLI's writing commands do);
    ``readonly=True`` never writes and never creates a store (``create`` defaults to ``not readonly``).
    """
    if memory:
        return GraphStore(None)
    return GraphStore(path or default_store_path(), readonly=readonly,
                      create=readonly is not True if create is None else create, wait=wait, on_wait=on_wait)
