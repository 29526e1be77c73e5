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

**Unload and replace, as close to the cost of a load as Oxigraph allows.** Oxigraph
deletes quad by quad in transactions; the cheapest way found here, predicate by predicate in
batches, costs about 11 µs of CPU a quad in a store of 5M quads, where a bulk load of a named
graph takes about 7-8 µs and copying the rest of the store into a fresh database 10-16 µs
(by lists of IRI subjects it was 23 µs; ``DELETE DATA``, ``Store.remove`` and
``clear_graph`` cost more still): the time goes into RocksDB's memtable skip list and the
indexed write batch of a transaction (perf), which a bulk load skips by writing table files.
So removing a graph either deletes its quads in bounded batches (flat memory, see
:meth:`~stepnc_graph.store.removal.Removal.delete_in_batches`), or -- when the graph is a large part of the
store -- rebuilds the database from the other graphs, which also gives its disk space
back at once; whichever costs less by those figures. Deleted quads keep their disk space
until the database is compacted, and a compaction rewrites all of it, so its cost grows with
the store, not with the program: an unload compacts once the quads deleted since the last
compaction reach a third of the store (:data:`~stepnc_graph.store.tuning.COMPACT_AT`; ``unload --compact`` at once).
Beside three programs of its size an unload then costs about one load (its deletes), and 1.5
loads when it compacts. A replacement there writes only what changed
(:mod:`stepnc_graph.store.replacement`): a re-load of the same file or of an edited
one costs 0.7-1.5 loads, where deleting the old version and loading the new one cost
2.1-2.5 (100k instances beside three such programs, measured; the ratios move with the load
they are measured against); a program of 1M instances
is staged on disk (see docs/loading.md for its figures). The new version is compared as the
load wrote it (:class:`Shadow`, :class:`Tee`), the old one as its load wrote it too
(:mod:`stepnc_graph.store.kept`), but for the lines with a blank node, read from the store: neither
is dumped. The deletes' write-ahead log is dropped at once
(:meth:`GraphStore._drop_write_ahead_log`); the strings that only removed quads used
stay until :meth:`GraphStore.compact` rebuilds the database.

An in-memory store (``path=None``) loads a new graph in place (dropping it on
failure) and a replacement into staging graphs moved into place in one SPARQL
Update transaction. The store directory is chosen by ``--store DIR``, else
``$STEPNC_GRAPH_STORE``, else ``./.stepnc-graph``.
"""

from __future__ import annotations

import errno
import gc
import io
import itertools
import json
import os
import shutil
import sys
import threading
import time
import uuid
from contextlib import contextmanager
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph.store.handoff import Handoff
from stepnc_graph.store.kept import KeptText, KeptTexts
from stepnc_graph.core.naming import STAGING, VOCABULARY_GRAPH, refuse_strangers
from stepnc_graph.store import tuning
from stepnc_graph.store.batches import ChunkStream, count_in, extend_in_calls, line_pieces
from stepnc_graph.store.difference import Tee
from stepnc_graph.store.errors import StoreBusy, StoreError, StoreWriteError
from stepnc_graph.store.removal import Removal
from stepnc_graph.store.replacement import Replacement
from stepnc_graph.store.files import (
    DEFAULT_STORE,
    DELETED_QUADS,
    FORMAT_VERSION,
    MARKER,
    STORE_ENV,
    clone_checkpoint,
    default_store_path,
    directory_bytes,
    fsync_dir,
)
from stepnc_graph.store.locks import LOCK_POLL, Locks, Writer, command_line
from stepnc_graph.store.contract import Capabilities, Chunk, Companion, Maintenance, Shadow, Store

__all__ = ["Capabilities", "Chunk", "Companion", "GraphStore", "Maintenance", "Shadow", "Store", "StoreBusy",
           "StoreError", "StoreWriteError", "Writer", "DEFAULT_STORE", "STORE_ENV", "FORMAT_VERSION", "default_store_path",
           "directory_bytes", "open_store"]


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


class GraphStore:
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
        #: whether the last unload or replacement compacted the database (see _settle)
        self.compacted = False
        self._deleted_after: int | None = None  # deleted_quads once this write commits (see _settle)
        self._deletes_logged = False  # work/'s write-ahead log holds batched deletes (see _commit)
        self._parked: ox.Store | None = None  # the database on disk while a replacement is staged
        self._tee: Tee | None = None  # the text a load writes (see Tee)
        #: the generation the running write started from (None: no write runs), the texts it kept
        #: and the graphs it touched (None: perhaps any), for the kept texts' index (see
        #: stepnc_graph.store.kept)
        self._since: str | None = None
        self._kept_written: dict[str, KeptText] = {}
        self._touched: set[str] | None = set()
        if self.path is None:
            self._store = ox.Store()
            return
        self._kept = KeptTexts(self._file("kept"))
        self._check_directory(create and readonly is not True)
        try:
            if readonly is None:
                self._open_lazily()
            elif readonly:
                self._open_reader()
            else:
                self._open_writer(wait, on_wait)
        except OSError as e:
            self.close()
            raise self._open_error(e) from None
        except BaseException:
            self.close()
            raise

    def _open_error(self, e: OSError) -> StoreError:
        if e.errno == errno.EROFS:
            return StoreError(f"cannot write to the store in {self.path}: it is on a read-only file system (info, "
                              "export, query and validate can still read it)")
        return StoreError(f"cannot open the store in {self.path}: {e.strerror or e}")

    # -- opening -----------------------------------------------------------------------

    def _check_directory(self, create: bool) -> None:
        path = self.path
        assert path is not None
        marker = path / MARKER
        if not path.exists():
            if not create:
                raise StoreError(f"no store at {path} (`stepnc-graph load` creates one)")
            try:
                path.mkdir(parents=True)
            except OSError as e:
                raise StoreError(f"cannot create the store directory {path}: {e.strerror or e}") from None
        elif not path.is_dir():
            raise StoreError(f"{path} is not a directory")
        if marker.exists():
            try:
                version = json.loads(marker.read_text()).get("format", 0)
            except (OSError, ValueError) as e:
                raise StoreError(f"{marker}: unreadable store marker ({e})") from None
            if version > FORMAT_VERSION:
                raise StoreError(f"{path}: store format {version} is newer than this stepnc-graph supports")
        elif any(path.iterdir()):
            raise StoreError(f"{path} is not empty and is not a stepnc-graph store")
        elif not create:
            raise StoreError(f"no store at {path} (`stepnc-graph load` creates one)")
        else:
            try:
                marker.write_text(json.dumps({"format": FORMAT_VERSION}) + "\n")
            except OSError as e:
                raise StoreError(f"cannot write to the store directory {path}: {e.strerror or e}") from None

    def _file(self, name: str) -> Path:
        assert self.path is not None
        return self.path / name

    def _writer(self) -> Writer:
        try:
            info = json.loads(self._file("write.lock").read_text() or "{}")
        except (OSError, ValueError):
            info = {}
        return Writer(info.get("pid"), info.get("command", ""), info.get("since", ""))

    def _open_writer(self, wait: bool | float, on_wait: Callable[[Writer], None] | None) -> None:
        self._write_fd = self._lock_writer(wait, on_wait)
        self._open_work()

    def _lock_writer(self, wait: bool | float, on_wait: Callable[[Writer], None] | None) -> int:
        """The writer's lock (its descriptor, with this process named in ``write.lock``), or
        :class:`StoreBusy` when another process holds it (after ``wait``)."""
        lock = self._file("write.lock")
        fd = Locks.try_lock(lock, shared=False)
        if fd is None:
            if not wait:
                raise StoreBusy(self.path, self._writer())  # type: ignore[arg-type]
            if on_wait is not None:
                on_wait(self._writer())
            deadline = None if wait is True else time.monotonic() + float(wait)
            while fd is None:
                if deadline is not None and time.monotonic() > deadline:
                    raise StoreBusy(self.path, self._writer())  # type: ignore[arg-type]
                time.sleep(LOCK_POLL)
                fd = Locks.try_lock(lock, shared=False)
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps({"pid": os.getpid(), "command": command_line(),
                                      "since": time.strftime("%Y-%m-%d %H:%M:%S")}).encode(), 0)
        except BaseException:
            Locks.release(fd)
            raise
        return fd

    def _open_work(self) -> None:
        """Open the writer's database (the writer's lock is held): the newest published state,
        recovered from it when a write was left unfinished."""
        self._migrate_format1()
        serving = self._file("work.serving")
        if self._current() is None:  # a new store: publish its empty first generation
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
            self._recover()
            self._store = ox.Store(str(self._file("work")))
        self._collect()
        self._kept.collect()

    def _open_lazily(self) -> None:
        """Read the published state; a new store first publishes its empty first generation
        (the writer's lock is taken for that moment only)."""
        if self._current() is None:
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
        fd = self._lock_writer(self._wait, self._on_wait)  # StoreBusy here changes nothing
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
                raise self._open_error(exc) from None
            raise
        self.generation = self._current()

    def _open_reader(self) -> None:
        if (self._file("oxigraph")).exists():  # format 1: needs the writer to migrate it
            with GraphStore(self.path, readonly=False, create=False):
                pass
        for _ in range(100):
            generation = self._current()
            if generation is None:
                raise StoreError(f"the store in {self.path} is being created; try again")
            fd = Locks.try_lock(self._file(generation + ".lock"), shared=True)
            if fd is not None and self._current() == generation and self._file(generation).is_dir():
                self._read_fd, self.generation = fd, generation
                self._store = ox.Store.read_only(str(self._file(generation)))
                return
            Locks.release(fd)
            time.sleep(0.01)  # a new generation was being published
        raise StoreError(f"cannot get a consistent view of {self.path}")

    def _current(self) -> str | None:
        try:
            return self._file("CURRENT").read_text().strip() or None
        except FileNotFoundError:
            return None

    def _migrate_format1(self) -> None:
        """A format-1 store (``oxigraph/``, ``journal/``): roll back an interrupted load, then
        adopt the database as ``work/`` and publish it."""
        old = self._file("oxigraph")
        if not old.exists():
            return
        journal = self._file("journal")
        if (journal / "loading").exists() and (journal / "checkpoint").exists():
            shutil.rmtree(old)
            (journal / "checkpoint").rename(old)
        shutil.rmtree(journal, ignore_errors=True)
        shutil.rmtree(self._file("work"), ignore_errors=True)
        old.rename(self._file("work"))
        self._store = ox.Store(str(self._file("work")))
        self._publish()
        self._file(MARKER).write_text(json.dumps({"format": FORMAT_VERSION}) + "\n")
        self._close_db()

    def _recover(self) -> None:
        """Make ``work/`` the published generation again unless it is known to be it."""
        current = self._current()
        assert current is not None
        work, dirty, stamp = self._file("work"), self._file("work.dirty"), self._file("work.generation")
        clean = work.is_dir() and not dirty.exists() and stamp.exists() and stamp.read_text().strip() == current
        if clean:
            return
        shutil.rmtree(work, ignore_errors=True)
        shutil.rmtree(self._file("rebuild"), ignore_errors=True)
        shutil.rmtree(self._file("difference"), ignore_errors=True)
        clone_checkpoint(self._file(current), work)
        stamp.write_text(current)
        dirty.unlink(missing_ok=True)

    # -- generations ----------------------------------------------------------------------

    def _begin(self) -> None:
        """Mark ``work/`` as possibly different from the published generation."""
        if self.path is None:
            return
        self.prepare_to_write()
        dirty = self._file("work.dirty")
        try:
            if not dirty.exists():
                dirty.write_text("")
                fsync_dir(self.path)
        except OSError as e:
            raise self._disk_error(e) or e from None
        self._since = self._current()

    def _disk_error(self, exc: BaseException) -> StoreWriteError | None:
        """A write's error as a :class:`StoreWriteError` naming the store, when the store's own
        files refused it (a full disk, a read-only one: Oxigraph's errors name no file, Python's a
        file in the store); None for any other error, such as an input file that cannot be read."""
        if not isinstance(exc, OSError) or isinstance(exc, StoreWriteError) or self.path is None:
            return None
        name = exc.filename
        if name is not None and not Path(os.path.abspath(name)).is_relative_to(Path(os.path.abspath(self.path))):
            return None
        reason = f"{exc.strerror} ({name})" if exc.strerror and name else exc.strerror or str(exc)
        error = StoreWriteError(f"cannot write to the store in {self.path}: {reason}; the store is as it was before")
        error.errno = exc.errno
        return error

    def _failed(self, exc: BaseException) -> None:
        """Roll a failed write back and raise its error (see :meth:`_disk_error`)."""
        self._rollback()
        if (error := self._disk_error(exc)) is not None:
            raise error from exc

    def _publish(self) -> None:
        """Checkpoint ``work/`` as the next generation and name it in ``CURRENT``."""
        assert self._store is not None and self.path is not None
        current = self._current()
        number = int(current[1:]) + 1 if current else 1
        name = f"g{number:06d}"
        tmp = self._file(name + ".tmp")
        shutil.rmtree(tmp, ignore_errors=True)
        self._store.flush()
        self._store.backup(str(tmp))
        tmp.rename(self._file(name))
        self._file(name + ".lock").touch()
        pointer = self._file("CURRENT.tmp")
        pointer.write_text(name + "\n")
        with open(pointer, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(pointer, self._file("CURRENT"))
        fsync_dir(self.path)
        self.generation = name
        self._file("work.generation").write_text(name)
        self._file("work.dirty").unlink(missing_ok=True)

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
        self._collect()
        self._file("work.serving").unlink(missing_ok=True)

    def _commit(self) -> None:
        if self.path is None:
            return
        if self._deletes_logged:  # before the checkpoint, which would copy the log
            self._drop_write_ahead_log()
        self._publish()
        self._count_deleted()
        written, touched, since = self._kept_written, self._touched, self._since
        self._kept_written, self._touched, self._since = {}, set(), None
        assert self.generation is not None
        self._kept.publish(self.generation, since, written, touched)
        self._collect()

    def _count_deleted(self) -> None:
        """Write the count of deleted quads this write leaves (see :meth:`_settle`), after the
        generation it belongs to is published. A writer killed in between leaves the count of the
        write before: the only effect is a later compaction."""
        after, self._deleted_after = self._deleted_after, None
        if after is None:
            return
        tmp = self._file(DELETED_QUADS + ".tmp")
        tmp.write_text(f"{after}\n")
        os.replace(tmp, self._file(DELETED_QUADS))

    @property
    def deleted_quads(self) -> int:
        """Quads deleted from the database since it was last compacted (0 in memory): the space
        their tombstones and dead data take comes back at the next compaction, which an unload
        or a replacement runs once they reach :data:`~stepnc_graph.store.tuning.COMPACT_AT` of the store."""
        try:
            return int(self._file(DELETED_QUADS).read_text())
        except (OSError, ValueError):
            return 0

    def _settle(self, deleted: int, held: int, compact: bool = False) -> None:
        """Count ``deleted`` quads against the database, which holds about ``held`` quads, and
        compact it (``optimize``: the space of deleted quads comes back) when the quads deleted
        since its last compaction reach :data:`~stepnc_graph.store.tuning.COMPACT_AT` of ``held``, or when ``compact``
        asks for it. Not at every unload: a compaction rewrites the whole database, so its cost
        grows with the store, not with what was deleted (see :data:`~stepnc_graph.store.tuning.COMPACT_AT`)."""
        pending = self.deleted_quads + deleted
        self.compacted = compact or pending >= tuning.COMPACT_AT * max(held, 1)
        if self.compacted:
            self._db.optimize()
            pending = 0
        self._deleted_after = pending

    def _drop_write_ahead_log(self) -> None:
        """Reopen ``work/`` so that RocksDB deletes the write-ahead log of batched deletes.

        The log holds every tombstone written (about 390 bytes a deleted quad: 530 MB for a
        100k-instance program) and RocksDB keeps it after the memtables are flushed, until the
        database is opened again (measured: a store of 1,200 MB of tables kept a 530 MB log
        after the unload's process ended). It is dropped before a generation is published: the
        checkpoint copies the live log, and a copy stayed in the published generation until the
        next write (a 100k-instance program unloaded beside three others: 207 MB, the store 1,465
        MB on disk where its database took 1,257). Reopening a 4M-quad store takes about 0.2 s.
        Skipped when someone else still holds the database (``store.oxigraph``): the next open
        drops it.
        """
        self._deletes_logged = False
        if sys.getrefcount(self._store) > 2:  # the attribute and the call's argument
            return
        self._close_db()
        self._store = ox.Store(str(self._file("work")))

    def _rollback(self) -> None:
        """Back to the published generation (the writer's lock is still held).

        ``work/`` stays marked dirty until it is rebuilt, so if the database cannot
        be reopened here (a caller still holds ``store.oxigraph``), the next
        writer's open recovers it.
        """
        if self.path is None:
            return
        self._deletes_logged = False  # work/ is rebuilt from the published generation
        self._deleted_after = None
        for kept in self._kept_written.values():
            self._kept.path(kept).unlink(missing_ok=True)
        self._kept_written, self._touched, self._since = {}, set(), None
        old, self._store = self._store, None
        # Called while an exception propagates. If anything still references the database (a
        # frame of that exception's traceback, typically after Ctrl-C, or a caller's
        # `store.oxigraph`), it stays open and may still write into work/ when it is finally
        # dropped, so work/ must not be rebuilt under it: leave it marked dirty (the next open
        # recovers it; readers read published generations and never see it), refuse further use
        # of this object, and let the caller see the original exception, not one of ours.
        held = old is not None and sys.getrefcount(old) > 2  # more than `old` and the call's argument
        del old
        gc.collect()
        if held:
            self._closed_because = (f"the store in {self.path} was rolled back, but this process still holds "
                                    f"its database (the failed operation's traceback); open it again")
            return
        try:
            self._recover()
            self._store = ox.Store(str(self._file("work")))
        except OSError as e:
            self._closed_because = (f"the store in {self.path} was rolled back on disk, but this process "
                                    f"could not reopen it ({e}); open it again")

    def _collect(self) -> None:
        """Delete generations no reader holds, except the current one."""
        assert self.path is not None
        current = self._current()
        for entry in self.path.iterdir():
            name = entry.name
            if name.endswith(".tmp") and entry.is_dir():
                shutil.rmtree(entry, ignore_errors=True)
                continue
            if not (name.startswith("g") and name[1:].isdigit() and entry.is_dir()) or name == current:
                continue
            fd = Locks.try_lock(self._file(name + ".lock"), shared=False)
            if fd is None:
                continue  # a reader still reads it; a later writer deletes it
            try:
                shutil.rmtree(entry, ignore_errors=True)
                self._file(name + ".lock").unlink(missing_ok=True)
            finally:
                Locks.release(fd)

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

    @property
    def _db(self) -> ox.Store:
        if self._store is None:
            raise StoreError(self._closed_because or "the store is closed")
        return self._store

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
        with self._write([graph, *companions, VOCABULARY_GRAPH]) as kept:
            how, present, removed, held = Removal(self).choose([graph, *companions], kept)
            if how == "delete":
                deleted = Replacement(self).replace(graph, chunks, before_commit, companions, kept,
                                                    in_memory=removed <= tuning.STAGE_IN_MEMORY_QUADS)
                self._settle(deleted, held)
            else:
                Removal(self).remove(how, present)
                self._load_kept(graph, chunks, before_commit, [graph, *companions])

    def remove_graph(self, graph: str, companions: Sequence[str] = (), compact: bool = False) -> bool:
        """Remove ``graph`` and its ``companions``; False if ``graph`` was not there.

        Deleted quads keep their disk space until the database is compacted: beside other
        programs that happens once enough was deleted (:meth:`_settle`), or now with
        ``compact``. Removed by a rebuild, the space comes back at once. Refuses what
        :meth:`replace_graph` refuses."""
        refuse_strangers(graph, companions)
        self.prepare_to_write()  # whether the graph is there, in the newest published state
        if not self._db.contains_named_graph(ox.NamedNode(graph)):
            return False
        with self._write([graph, *companions]) as kept:
            how, present, removed, held = Removal(self).choose([graph, *companions], kept)
            Removal(self).remove(how, present)
            if how == "delete":
                self._settle(removed, held - removed, compact)
        return True

    @contextmanager
    def _write(self, touches: list[str] | None) -> Iterator[dict[str, KeptText]]:
        """One write to the store on disk, the only way one is made: ``work/`` marked dirty, the
        graphs it ``touches`` noted (None: it rewrites the database, no kept text is read), then
        committed as the next generation, or rolled back on any exception, which is raised again
        (:meth:`_failed`). Yields the kept texts that describe the database now."""
        self._begin()
        try:
            kept: dict[str, KeptText] = {}
            if touches is not None:  # an unload or a replacement (not a compaction)
                self.compacted = False
                kept = self._usable_kept()
                self._touch(touches)
            yield kept
            self._commit()
        except BaseException as exc:
            self._failed(exc)
            raise

    def _usable_kept(self) -> dict[str, KeptText]:
        """The kept texts that describe the database now: those of the generation it was
        published as, but for graphs changed since by writes outside a load."""
        if self._touched is None:
            return {}
        return {g: k for g, k in self._kept.valid(self._since).items() if g not in self._touched}

    def _touch(self, graphs: Sequence[str] | None) -> None:
        """Note that the current write changes ``graphs`` (None: perhaps any), whose kept texts
        then describe them no more (see :mod:`stepnc_graph.store.kept`)."""
        if graphs is None:
            self._touched = None
        elif self._touched is not None:
            self._touched.update(graphs)

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
        self._kept_written.update(tee.keep())

    @property
    def _disk(self) -> ox.Store:
        """The database on disk, also while a replacement is staged in memory."""
        return self._parked if self._parked is not None else self._db

    def _bulk_load(self, graph: str, chunks: Iterable[Chunk],
                   target: Callable[[str], str] = lambda name: name, in_memory: bool | None = None) -> None:
        """Stream ``chunks`` into ``graph`` with one bulk loader per core.

        Measured on a 2-core machine: one ``bulk_load`` call ingests ~125k
        quads/s into a named graph on disk using one core; two concurrent calls
        on halves of the data reach ~230k quads/s. So the producer (this
        thread: parse and map) fills a bounded queue and ``LOAD_THREADS``
        threads each run a streaming ``bulk_load`` over it (pyoxigraph releases
        the GIL while loading; an in-memory store is fed differently, see
        :data:`~stepnc_graph.store.tuning.MEMORY_BATCH_CHARS`). Chunks end at instance boundaries and blank-node
        labels are unique per load, so every thread's document is self-contained.
        A :class:`Companion` chunk is loaded on its own into ``target(its graph)``.
        """
        in_memory = self.path is None if in_memory is None else in_memory
        threads_n = 1 if in_memory else tuning.LOAD_THREADS  # see tuning.MEMORY_BATCH_CHARS
        # the chunks encoded once (here, also for the tee): the main graph's as bytes, a
        # companion's as (its graph, bytes). The first error of any thread aborts the hand-off,
        # which stops the producer and every worker (see stepnc_graph.store.handoff).
        work: Handoff[bytes | tuple[str, bytes]] = Handoff(2 * threads_n)
        errors: list[BaseException] = []
        main = ox.NamedNode(graph)
        # No local name holds the database: a failure's traceback keeps this frame
        # alive, and the rollback must be able to close the database.

        def worker() -> None:
            ended = False

            def pull(budget: int, large: list[bytes | tuple[str, bytes]]) -> Iterator[bytes]:
                """Chunks for one streaming bulk_load call: at most ``budget`` characters' worth;
                a chunk too large for the streaming reader, or a companion's, ends the call and
                goes to ``large``."""
                nonlocal ended
                used = 0
                while used < budget:
                    item = work.get()
                    if item is None:
                        ended = True
                        return
                    if type(item) is not bytes or len(item) > tuning.DIRECT_CHARS:
                        large.append(item)
                        return
                    used += len(item)
                    yield item

            try:
                while not ended:
                    large: list[bytes | tuple[str, bytes]] = []
                    if in_memory:
                        data = b"".join(pull(tuning.MEMORY_BATCH_CHARS, large))
                        if data:
                            self._db.bulk_load(data, ox.RdfFormat.N_TRIPLES, to_graph=main, lenient=True)
                    else:
                        stream = io.BufferedReader(ChunkStream(pull(tuning.BATCH_CHARS, large)), 1 << 20)
                        self._db.bulk_load(stream, ox.RdfFormat.N_TRIPLES, to_graph=main, lenient=True)
                    for item in large:
                        into, data = ((ox.NamedNode(target(item[0])), item[1]) if isinstance(item, tuple)
                                      else (main, item))
                        self._db.bulk_load(data, ox.RdfFormat.N_TRIPLES, to_graph=into, lenient=True)
                    if work.aborted:  # another thread failed: what this one loaded is rolled back
                        return
            except BaseException as exc:  # noqa: BLE001 -- raised by the producer thread
                errors.append(exc)
                work.abort()

        threads = [threading.Thread(target=worker, daemon=True) for _ in range(threads_n)]
        for t in threads:
            t.start()
        try:
            for chunk in chunks:
                into, data = (graph, chunk.encode("utf-8")) if type(chunk) is str else (
                    chunk.graph, chunk.text.encode("utf-8"))  # type: ignore[union-attr]
                if self._tee is not None:
                    self._tee.write_bytes(into, data)
                if isinstance(chunk, Shadow):  # the load writes those itself (see Shadow)
                    continue
                if not work.put(data if type(chunk) is str else (into, data)):
                    break  # a worker failed
        except BaseException:
            work.abort()
            raise
        finally:
            work.close()
            for t in threads:
                t.join()
        if errors:
            raise errors[0]

    def update(self, sparql: str) -> None:
        """One SPARQL Update (one transaction); for writes inside a load's ``before_commit``
        (into the graphs of that load: outside a load, it may have changed any graph)."""
        self.prepare_to_write()
        self._touch_any_outside_a_write()
        self._db.update(sparql)

    def _touch_any_outside_a_write(self) -> None:
        if self._since is None:
            self._touch(None)

    def add_ntriples(self, graph: str, text: str, bulk: bool = False) -> None:
        """Add N-Triples to ``graph`` (for use inside ``before_commit``): in one transaction, or
        with ``bulk`` through Oxigraph's bulk loader (faster for many, not transactional: the load
        around it is)."""
        self.prepare_to_write()
        if self._tee is not None:
            self._tee.write(graph, text)
        self._touch([graph])
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
        self._touch_any_outside_a_write()
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
        self._touch([graph])
        self._db.bulk_load(text.encode("utf-8"), ox.RdfFormat.TURTLE, to_graph=ox.NamedNode(graph))

    def compact(self, progress: Callable[[int, int], None] | None = None) -> None:
        """Rebuild the database from its graphs, as one atomic write (``stepnc-graph compact``).

        An unload beside other programs compacts RocksDB's tables (once enough was deleted,
        see :data:`~stepnc_graph.store.tuning.COMPACT_AT`), but Oxigraph never deletes the strings (literals, IRIs) that
        only removed quads used (measured: a 100k-instance program unloaded beside three others
        left 1,200 MB on disk where a rebuilt store takes 945 MB), so a store whose programs come
        and go keeps growing. A rebuild keeps only what the graphs hold. It copies every quad
        (about 16 µs of CPU each), so it is a maintenance step, not part of every unload.
        ``progress(done, total)`` counts the quads copied. An in-memory store has nothing to give
        back.
        """
        with self._write(None):
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

    @property
    def server(self) -> None:
        """None: the embedded Oxigraph database answers (see :meth:`Store.server`)."""
        return None

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

    def all_graphs(self) -> list[str]:
        """Every named graph but staging ones: with the vocabulary and the derived layers."""
        return sorted(g.value for g in self._db.named_graphs()
                      if isinstance(g, ox.NamedNode) and not g.value.startswith(STAGING))

    def has_graph(self, graph: str) -> bool:
        return self._db.contains_named_graph(ox.NamedNode(graph))

    def query(self, sparql: str, **kwargs: Any) -> Any:
        return self._db.query(sparql, **kwargs)

    def count(self, graph: str | None = None) -> int:
        """Quads in ``graph`` (all quads for None), counted by Oxigraph."""
        return len(self._db) if graph is None else count_in(self._db, graph)

    def quads(self, graph: str | None = None) -> Iterator[ox.Quad]:
        return iter(self._db.quads_for_pattern(None, None, None, ox.NamedNode(graph) if graph else None))

    def quads_for_pattern(self, subject: Any, predicate: Any, obj: Any, graph: Any = None) -> Iterator[ox.Quad]:
        """Oxigraph's ``quads_for_pattern``, for readers (unlike :attr:`oxigraph`, it keeps the
        kept texts of a writer valid)."""
        return iter(self._db.quads_for_pattern(subject, predicate, obj, graph))

    def dump(self, fmt: ox.RdfFormat, graph: str | None = None, prefixes: dict[str, str] | None = None) -> bytes:
        kwargs: dict[str, Any] = {}
        if graph is not None:
            kwargs["from_graph"] = ox.NamedNode(graph)
        if prefixes and fmt in (ox.RdfFormat.TURTLE, ox.RdfFormat.TRIG):
            kwargs["prefixes"] = prefixes
        out = self._db.dump(None, fmt, **kwargs)
        return out if out is not None else b""

    @property
    def oxigraph(self) -> ox.Store:
        """The underlying pyoxigraph store (for SPARQL users who want it directly). Writes through
        it are not seen by the store: a writer that hands it out keeps no load's text beyond its
        next write (see :mod:`stepnc_graph.store.kept`). A store opened read-only, or lazily and
        not written yet, hands out the published generation, read-only: writes through it need
        ``open_store(..., readonly=False)`` or :meth:`prepare_to_write` first."""
        if self.path is None or self._write_fd is not None:
            self._touch(None)
        return self._db

    def rdflib_dataset(self) -> Any:
        """An rdflib ``Dataset`` over the same data (oxrdflib), for rdflib/pySHACL users."""
        import rdflib
        from oxrdflib.store import OxigraphStore

        return rdflib.Dataset(store=OxigraphStore(store=self.oxigraph))


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
