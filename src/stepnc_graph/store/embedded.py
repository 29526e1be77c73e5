"""The embedded Oxigraph store: :class:`GraphStore` on disk, :class:`MemoryStore` in memory.

The store on disk is a façade over single-concern modules: the directory and its generations
(:mod:`.directory`), the process locks (:mod:`.locks`), the write transaction
(:mod:`.transaction`), threaded bulk loading (:mod:`.bulk`), removal and the compaction policy
(:mod:`.removal`), replacement by difference (:mod:`.replacement`) and the kept texts
(:mod:`.kept`). What it keeps itself is opening (a reader, a writer, lazily), the calls of the
:class:`~stepnc_graph.store.contract.Store` contract, and which concern each one goes to.
"""

from __future__ import annotations

import gc
import itertools
import os
import shutil
import sys
import time
import uuid
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.naming import STAGING, VOCABULARY_GRAPH, refuse_strangers
from stepnc_graph.store import directory, tuning
from stepnc_graph.store.batches import extend_in_calls, line_pieces
from stepnc_graph.store.bulk import BulkLoad
from stepnc_graph.store.contract import Capabilities, Chunk, Maintenance
from stepnc_graph.store.difference import Tee
from stepnc_graph.store.errors import StoreError
from stepnc_graph.store.files import DELETED_QUADS, directory_bytes, fsync_dir
from stepnc_graph.store.kept import KeptTexts
from stepnc_graph.store.reading import OxigraphReads
from stepnc_graph.store.locks import Locks, Writer, lock_writer
from stepnc_graph.store.removal import Removal
from stepnc_graph.store.replacement import Replacement
from stepnc_graph.store.transaction import Transaction


class GraphStore(OxigraphReads):
    """Named graphs in an Oxigraph store. ``path=None`` is a throw-away in-memory store.

    On disk, ``readonly=False`` takes the writer's lock at once and holds it
    until :meth:`close`; ``readonly=True`` opens the published state for
    reading, never blocks and never changes anything; the default (``None``)
    reads like ``readonly=True`` until the first write, which takes the lock
    then (:meth:`prepare_to_write`). ``create=False`` refuses a directory that
    is not a store yet (readers never create). ``wait`` makes a writer wait for
    the lock (``True``, or a number of seconds) instead of raising
    :class:`StoreBusy`; ``on_wait(writer)`` is called once before waiting.
    """

    def __new__(cls, path: Path | str | None = None, **_options: Any) -> GraphStore:
        """``GraphStore(None)`` is a :class:`MemoryStore`; a directory, the store on disk."""
        return super().__new__(MemoryStore if cls is GraphStore and path is None else cls)

    def __init__(self, path: Path | str | None = None, *, readonly: bool | None = None, create: bool = True,
                 wait: bool | float = False, on_wait: Callable[[Writer], None] | None = None) -> None:
        self.path = Path(path) if path is not None else None
        #: never writes (``readonly=True``); a store opened lazily (``readonly=None``) is not read-only
        self.readonly = readonly is True
        self._wait, self._on_wait = wait, on_wait  # for the writer's lock taken at the first write
        self._write_fd: int | None = None
        self._read_fd: int | None = None
        self._held_read_fd: int | None = None  # a generation read before the first write (prepare_to_write)
        self._store: ox.Store | None = None
        self._closed_because: str | None = None  # why _db refuses use (a rollback that could not reopen)
        self.generation: str | None = None
        #: how the last graph removal was done on disk: "delete" or "rebuild" (for tests and benchmarks)
        self.last_removal: str | None = None
        #: what the last replacement by difference wrote: quads deleted and inserted (and of
        #: these, with a blank node), blank nodes of the new version that kept the old version's
        #: node (see stepnc_graph.store.replacement)
        self.last_difference: dict[str, int] = {}
        #: whether the last unload or replacement compacted the database (see Transaction.settle)
        self.compacted = False
        self._parked: ox.Store | None = None  # the database on disk while a replacement is staged
        self._tee: Tee | None = None  # the text a load writes (see Tee)
        #: the running write's state, and how a write begins, commits or rolls back
        self._tx = Transaction(self)
        if self.path is None:
            self._store = ox.Store()
            return
        self._kept = KeptTexts(self._file("kept"))
        directory.check_directory(self.path, create and readonly is not True)
        try:
            if readonly is None:
                self._open_lazily()
            elif readonly:
                self._open_reader()
            else:
                self._open_writer(wait, on_wait)
        except OSError as e:
            self.close()
            raise directory.open_error(self.path, e) from None
        except BaseException:
            self.close()
            raise

    # -- opening -----------------------------------------------------------------------

    @property
    def _dir(self) -> Path:
        assert self.path is not None
        return self.path

    def _file(self, name: str) -> Path:
        return self._dir / name

    def _open_writer(self, wait: bool | float, on_wait: Callable[[Writer], None] | None) -> None:
        self._write_fd = lock_writer(self._dir, wait, on_wait)
        self._open_work()

    def _open_work(self) -> None:
        """Open the writer's database (the writer's lock is held): the newest published state,
        recovered from it when a write was left unfinished."""
        self.generation = directory.migrate_format1(self._dir) or self.generation
        serving = self._file("work.serving")
        if directory.current(self._dir) is None:  # a new store: publish its empty first generation
            shutil.rmtree(self._file("work"), ignore_errors=True)
            self._store = ox.Store(str(self._file("work")))
            self._publish()
        elif serving.exists() and not self._file("work.dirty").exists() and self._file("work").is_dir():
            # `serve --writable` stopped without publishing: Oxigraph ran every update in a
            # transaction, so its database is consistent; publish it rather than lose the updates
            self._store = ox.Store(str(self._file("work")))
            self._publish()
            serving.unlink()
        else:
            serving.unlink(missing_ok=True)
            directory.recover(self._dir)
            self._store = ox.Store(str(self._file("work")))
        directory.collect(self._dir)
        self._kept.collect()

    def _open_lazily(self) -> None:
        """Read the published state; a new store first publishes its empty first generation
        (the writer's lock is taken for that moment only)."""
        if directory.current(self._dir) is None:
            with GraphStore(self.path, readonly=False, wait=self._wait, on_wait=self._on_wait):
                pass
        self._open_reader()

    def prepare_to_write(self) -> None:
        """Take the writer's lock now, if this store does not hold it yet (opened lazily), and read
        the newest published state from then on: a write that reads the store first (which graphs
        a program has, whether a graph is there) reads what it changes.

        Another process writing: :class:`StoreBusy` (or a wait, per ``wait``), and the store
        still reads the generation it read. The lock is then held until :meth:`close`.
        """
        if self.path is None or self._write_fd is not None:
            return
        if self.readonly:
            raise StoreError(f"the store in {self.path} was opened read-only")
        fd = lock_writer(self._dir, self._wait, self._on_wait)  # StoreBusy here changes nothing
        reader, read_fd = self._store, self._read_fd
        self._store = None
        # someone still holds the generation's database (``store.oxigraph``): keep its lock until
        # close, so that no writer deletes the generation under it
        self._held_read_fd = read_fd if sys.getrefcount(reader) > 2 else None
        del reader
        gc.collect()  # pyoxigraph releases a database when it is collected
        if self._held_read_fd is None:
            Locks.release(read_fd)
        self._read_fd, self._write_fd = None, fd
        try:
            self._open_work()
        except BaseException as exc:
            self._close_db()
            Locks.release(self._write_fd)
            self._write_fd = None
            self._open_reader()  # still a reader, of the newest published state
            if isinstance(exc, OSError):
                raise directory.open_error(self._dir, exc) from None
            raise
        self.generation = directory.current(self._dir)

    def _open_reader(self) -> None:
        if (self._file("oxigraph")).exists():  # format 1: needs the writer to migrate it
            with GraphStore(self.path, readonly=False, create=False):
                pass
        for _ in range(100):
            generation = directory.current(self._dir)
            if generation is None:
                raise StoreError(f"the store in {self.path} is being created; try again")
            fd = Locks.try_lock(self._file(generation + ".lock"), shared=True)
            if fd is not None and directory.current(self._dir) == generation and self._file(generation).is_dir():
                self._read_fd, self.generation = fd, generation
                self._store = ox.Store.read_only(str(self._file(generation)))
                return
            Locks.release(fd)
            time.sleep(0.01)  # a new generation was being published
        raise StoreError(f"cannot get a consistent view of {self.path}")

    # -- generations ----------------------------------------------------------------------

    def _publish(self) -> None:
        """Checkpoint ``work/`` as the next generation and name it in ``CURRENT``."""
        self.generation = directory.publish(self._dir, self._db)

    def serving(self) -> Path:
        """Hand the writer's database to another process (``serve --writable``): it is closed
        here and marked as being served; :meth:`served` takes it back and publishes it."""
        if self.path is None or self.readonly:
            raise StoreError("only an on-disk store opened for writing can be served writable")
        self.prepare_to_write()
        self._close_db()
        self._file("work.serving").write_text(str(os.getpid()))
        fsync_dir(self.path)
        return self._file("work")

    def served(self) -> None:
        """The serving process stopped: reopen the database and publish what it changed."""
        self._store = ox.Store(str(self._file("work")))
        self._publish()
        directory.collect(self._dir)
        self._file("work.serving").unlink(missing_ok=True)

    @property
    def deleted_quads(self) -> int:
        """Quads deleted from the database since it was last compacted (0 in memory): the space
        their tombstones and dead data take comes back at the next compaction, which an unload
        or a replacement runs once they reach :data:`~stepnc_graph.store.tuning.COMPACT_AT` of the store."""
        try:
            return int(self._file(DELETED_QUADS).read_text())
        except (OSError, ValueError):
            return 0

    # -- closing ------------------------------------------------------------------------------

    def _close_db(self) -> None:
        if self._store is not None:
            if self.path is not None and self._write_fd is not None:  # the writer's database
                self._store.flush()
            self._store = None
            if self.path is not None:  # an in-memory store has no files or lock to release
                gc.collect()  # pyoxigraph releases the database (and its RocksDB lock) when collected

    def close(self) -> None:
        """Release the database and the store's locks. Idempotent."""
        self._close_db()
        Locks.release(self._read_fd)
        Locks.release(self._write_fd)
        Locks.release(self._held_read_fd)
        self._read_fd = self._write_fd = self._held_read_fd = None

    def __del__(self) -> None:  # a store dropped without close() still releases its locks
        try:
            self.close()
        except Exception:  # noqa: BLE001 -- nothing to report to during garbage collection
            pass

    def __enter__(self) -> "GraphStore":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- writing ----------------------------------------------------------------------

    def replace_graph(self, graph: str, chunks: Iterable[Chunk],
                      before_commit: Callable[[Callable[[str], str]], None] | None = None,
                      companions: Sequence[str] = ()) -> None:
        """Atomically make ``graph`` hold exactly the N-Triples in ``chunks``.

        ``companions`` are graphs that belong to ``graph`` (its derived layer):
        they are emptied with it and may be written by :class:`Companion`
        chunks and by ``before_commit``.
        ``before_commit(target)`` runs after the data is in the store but before
        the load is committed; ``target(name)`` gives the graph to write now for
        ``graph`` or a companion (a staging graph, for an in-memory
        replacement). An exception from it (or from ``chunks``) rolls back.
        A reserved name, or a companion outside ``graph``'s companion namespace, is refused
        (:func:`~stepnc_graph.core.naming.refuse_strangers`); which program may take which name
        is for the writing commands to check (:class:`~stepnc_graph.core.naming.GraphLayout`).
        """
        refuse_strangers(graph, companions)
        self.prepare_to_write()
        with self._tx.write([graph, *companions, VOCABULARY_GRAPH]) as kept:
            how, present, removed, held = Removal(self).choose([graph, *companions], kept)
            if how == "delete":
                deleted = Replacement(self).replace(graph, chunks, before_commit, companions, kept,
                                                    in_memory=removed <= tuning.STAGE_IN_MEMORY_QUADS)
                self._tx.settle(deleted, held)
            else:
                Removal(self).remove(how, present)
                self._load_kept(graph, chunks, before_commit, [graph, *companions])

    def remove_graph(self, graph: str, companions: Sequence[str] = (), compact: bool = False) -> bool:
        """Remove ``graph`` and its ``companions``; False if ``graph`` was not there.

        Deleted quads keep their disk space until the database is compacted: beside other
        programs that happens once enough was deleted (:meth:`Transaction.settle`), or now with
        ``compact``. Removed by a rebuild, the space comes back at once. Refuses what
        :meth:`replace_graph` refuses."""
        refuse_strangers(graph, companions)
        self.prepare_to_write()  # whether the graph is there, in the newest published state
        if not self._db.contains_named_graph(ox.NamedNode(graph)):
            return False
        with self._tx.write([graph, *companions]) as kept:
            how, present, removed, held = Removal(self).choose([graph, *companions], kept)
            Removal(self).remove(how, present)
            if how == "delete":
                self._tx.settle(removed, held - removed, compact)
        return True

    def _load_kept(self, graph: str, chunks: Iterable[Chunk],
                   before_commit: Callable[[Callable[[str], str]], None] | None, names: list[str]) -> None:
        """Load ``graph`` into the database as it is (no old version there), complete it, and keep
        the text written into the graphs ``names`` (:mod:`stepnc_graph.store.kept`)."""
        self._tee = tee = Tee(names, kept=self._kept.writing(names))
        try:
            self._bulk_load(graph, chunks)
            if before_commit is not None:
                before_commit(lambda name: name)
        except BaseException:
            tee.discard()
            raise
        finally:
            self._tee = None
            tee.close()
        self._tx.kept_written.update(tee.keep())

    @property
    def _disk(self) -> ox.Store:
        """The database on disk, also while a replacement is staged in memory."""
        return self._parked if self._parked is not None else self._db

    def _bulk_load(self, graph: str, chunks: Iterable[Chunk],
                   target: Callable[[str], str] = lambda name: name, in_memory: bool | None = None) -> None:
        """Stream ``chunks`` into ``graph`` with one bulk loader per core (:mod:`.bulk`); a
        :class:`Companion` chunk is loaded on its own into ``target(its graph)``."""
        BulkLoad(self, graph, target, self.path is None if in_memory is None else in_memory).run(graph, chunks)

    def update(self, sparql: str) -> None:
        """One SPARQL Update (one transaction); for writes inside a load's ``before_commit``
        (into the graphs of that load: outside a load, it may have changed any graph)."""
        self.prepare_to_write()
        self._tx.touch_any_outside_a_write()
        self._db.update(sparql)

    def add_ntriples(self, graph: str, text: str, bulk: bool = False) -> None:
        """Add N-Triples to ``graph`` (for use inside ``before_commit``): in one transaction, or
        with ``bulk`` through Oxigraph's bulk loader (faster for many, not transactional: the load
        around it is)."""
        self.prepare_to_write()
        if self._tee is not None:
            self._tee.write(graph, text)
        self._tx.touch([graph])
        if bulk or len(text) > tuning.DIRECT_CHARS:
            for piece in line_pieces(text, tuning.BATCH_CHARS):  # the bulk loader's memory grows with a call
                self._db.bulk_load(piece.encode("utf-8"), ox.RdfFormat.N_TRIPLES, to_graph=ox.NamedNode(graph))
        else:
            self._db.load(text, ox.RdfFormat.N_TRIPLES, to_graph=ox.NamedNode(graph))

    def add_quads(self, quads: Iterable[ox.Quad]) -> int:
        """Add ``quads`` (for use inside ``before_commit``), pulled one at a time: up to
        :data:`~stepnc_graph.store.tuning.TRANSACTION_QUADS` in one transaction, more through the bulk loader in calls of
        :data:`~stepnc_graph.store.tuning.INSERT_BATCH` (a transaction holds all of its quads in memory, several times
        their size). Returns how many were added."""
        self.prepare_to_write()
        self._tx.touch_any_outside_a_write()
        it = iter(quads)
        first = list(itertools.islice(it, tuning.TRANSACTION_QUADS + 1))
        if len(first) <= tuning.TRANSACTION_QUADS:
            self._db.extend(first)
            return len(first)
        return sum(extend_in_calls(self._db, itertools.chain(first, it), tuning.INSERT_BATCH))

    def add_turtle(self, graph: str, text: str) -> None:
        """Add a Turtle document to ``graph`` (inside ``before_commit``, like :meth:`add_ntriples`):
        parsed by Oxigraph in one call, with no Python object per triple."""
        self.prepare_to_write()
        self._tx.touch([graph])
        self._db.bulk_load(text.encode("utf-8"), ox.RdfFormat.TURTLE, to_graph=ox.NamedNode(graph))

    def compact(self, progress: Callable[[int, int], None] | None = None) -> None:
        """Rebuild the database from its graphs, as one atomic write (``stepnc-graph compact``).

        An unload beside other programs compacts RocksDB's tables (once enough was deleted,
        see :data:`~stepnc_graph.store.tuning.COMPACT_AT`), but Oxigraph never deletes the strings
        (literals, IRIs) that only removed quads used, so a store whose programs come and go keeps
        growing; a rebuild keeps only what the graphs hold. It copies every quad, so it is a
        maintenance step, not part of every unload (figures: docs/loading.md, ``compact``).
        ``progress(done, total)`` counts the quads copied. An in-memory store has nothing to give
        back.
        """
        with self._tx.write(None):
            Removal(self).rebuild_without(set(), progress)
            self._db.optimize()  # the bulk loader's tables, merged now rather than beside the published ones

    def disk_bytes(self) -> int:
        """Bytes the store directory takes on disk (a file hard-linked into several generations
        counted once); 0 for an in-memory store."""
        assert self.path is not None
        return directory_bytes(self.path)

    # -- reading ------------------------------------------------------------------------

    @property
    def capabilities(self) -> Capabilities:
        """Persistent and compactable; embedded Oxigraph: blank nodes as given, cheap local reads."""
        return Capabilities(persistent=True, blank_node_writes=True, local_reads=True, compactable=True)

    @property
    def location(self) -> str:
        """The store's absolute directory."""
        assert self.path is not None
        return str(self.path.resolve())

    def maintenance(self) -> Maintenance:
        """Deleted quads waiting for a compaction and bytes on disk (0 and 0 in memory)."""
        return Maintenance(self.deleted_quads, self.disk_bytes())

    def local_copy(self, graphs: str | Sequence[str] | None = None) -> GraphStore:
        """An in-memory store holding a copy of ``graphs`` (one, several, or every graph)."""
        copy = GraphStore(None)
        names = self.all_graphs() if graphs is None else [graphs] if isinstance(graphs, str) else graphs
        for name in names:
            copy._db.bulk_extend(self.quads(name))
        return copy

    @property
    def oxigraph(self) -> ox.Store:
        """The underlying pyoxigraph store (for SPARQL users who want it directly). Writes through
        it are not seen by the store: a writer that hands it out keeps no load's text beyond its
        next write (see :mod:`stepnc_graph.store.kept`). A store opened read-only, or lazily and
        not written yet, hands out the published generation, read-only: writes through it need
        ``open_store(..., readonly=False)`` or :meth:`prepare_to_write` first."""
        if self.path is None or self._write_fd is not None:
            self._tx.touch(None)
        return self._db

class MemoryStore(GraphStore):
    """A throw-away store in memory (``GraphStore(None)``, ``open_store(memory=True)``): no files,
    locks, generations or compaction. A new graph is loaded in place (dropped on failure); a
    replacement goes into staging graphs moved into place in one SPARQL Update transaction."""

    def replace_graph(self, graph: str, chunks: Iterable[Chunk],
                      before_commit: Callable[[Callable[[str], str]], None] | None = None,
                      companions: Sequence[str] = ()) -> None:
        """As :meth:`GraphStore.replace_graph`, in memory."""
        refuse_strangers(graph, companions)
        self._replace_in_memory(graph, chunks, before_commit, companions)

    def remove_graph(self, graph: str, companions: Sequence[str] = (), compact: bool = False) -> bool:
        """Remove ``graph`` and its ``companions``; False if ``graph`` was not there."""
        refuse_strangers(graph, companions)
        if not self._db.contains_named_graph(ox.NamedNode(graph)):
            return False
        for name in (graph, *companions):
            self._db.remove_graph(ox.NamedNode(name))
        return True

    def compact(self, progress: Callable[[int, int], None] | None = None) -> None:
        """Nothing to give back in memory."""

    @property
    def deleted_quads(self) -> int:
        return 0

    def disk_bytes(self) -> int:
        return 0

    @property
    def capabilities(self) -> Capabilities:
        """Not persistent (a load leaves the vocabulary graph out of it); embedded Oxigraph."""
        return Capabilities(persistent=False, blank_node_writes=True, local_reads=True, compactable=False)

    @property
    def location(self) -> str:
        return "memory"

    def _replace_in_memory(self, graph: str, chunks: Iterable[Chunk],
                           before_commit: Callable[[Callable[[str], str]], None] | None,
                           companions: Sequence[str]) -> None:
        """A new graph loads in place (rollback: drop it and its companions); a replacement is
        written under staging names, then moved into place in one SPARQL Update transaction.

        Moving copies quad by quad, so a new graph (the usual case of a throw-away store)
        skips it.
        """
        names = (graph, *companions)
        replacing = any(self._db.contains_named_graph(ox.NamedNode(n)) for n in names)
        staging = {n: STAGING + uuid.uuid4().hex if replacing else n for n in names}
        try:
            self._bulk_load(staging[graph], chunks, lambda name: staging[name])
            if before_commit is not None:
                before_commit(lambda name: staging[name])
        except BaseException:
            for name in staging.values():
                self._db.remove_graph(ox.NamedNode(name))
            raise
        if replacing:
            self._db.update(" ; ".join(f"DROP SILENT GRAPH {ox.NamedNode(name)} ; MOVE SILENT GRAPH <{tmp}> TO "
                                       f"{ox.NamedNode(name)}" for name, tmp in staging.items()))
