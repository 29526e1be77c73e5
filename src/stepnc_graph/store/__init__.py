"""The graph store: an embedded Oxigraph database, on disk by default.

Layout of a store directory (format 2)::

    DIR/stepnc-graph-store.json   marker (format version)
    DIR/write.lock                the writer holds an exclusive lock on it (and writes its pid there)
    DIR/CURRENT                   the name of the published generation, e.g. "g000007"
    DIR/g000007/                  a published generation: an Oxigraph checkpoint nobody writes to
    DIR/g000007.lock              readers hold a shared lock on it while they read that generation
    DIR/work/                     the writer's read-write database
    DIR/work.dirty                present while work/ may differ from the published generation
    DIR/deleted-quads             quads deleted since work/ was last compacted (see COMPACT_AT)
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
:meth:`GraphStore._delete_in_batches`), or -- when the graph is a large part of the
store -- rebuilds the database from the other graphs, which also gives its disk space
back at once; whichever costs less by those figures. Deleted quads keep their disk space
until the database is compacted, and a compaction rewrites all of it, so its cost grows with
the store, not with the program: an unload compacts once the quads deleted since the last
compaction reach a third of the store (:data:`COMPACT_AT`; ``unload --compact`` at once).
Beside three programs of its size an unload then costs about one load (its deletes), and 1.5
loads when it compacts. A replacement there writes only what changed
(:meth:`GraphStore._replace_by_difference`): a re-load of the same file or of an edited
one costs 0.7-1.5 loads, where deleting the old version and loading the new one cost
2.1-2.5 (100k instances beside three such programs, measured; the ratios move with the load
they are measured against); a program of 1M instances
is staged on disk (see docs/loading.md for its figures). The new version is compared as the
load wrote it (:class:`Shadow`, :class:`_Tee`), the old one as its load wrote it too
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
import fcntl
import gc
import hashlib
import io
import itertools
import json
import os
import queue
import shutil
import sys
import threading
import time
import traceback
import uuid
import zlib
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO, Protocol

import pyoxigraph as ox

from stepnc_graph.store.handoff import Handoff
from stepnc_graph.store.kept import BLANK_OBJECT, KeptText, KeptTexts, KeptWriting, read_without_blank_nodes
from stepnc_graph.core.naming import P21_NS, STAGING, VOCABULARY_GRAPH, GraphLayout, refuse_strangers

STORE_ENV = "STEPNC_GRAPH_STORE"
DEFAULT_STORE = ".stepnc-graph"
FORMAT_VERSION = 2
MARKER = "stepnc-graph-store.json"
LOAD_THREADS = max(1, min(4, os.cpu_count() or 1))
#: N-Triples characters per bulk_load call (about 120k triples). Oxigraph's bulk
#: loader and RocksDB hold memory in proportion to one call; 12M characters
#: instead of 50M cut the peak RSS of a 100k-instance load from 685 MB to 280 MB
#: at the same CPU time (measured).
BATCH_CHARS = 12_000_000
#: A chunk this large (it holds a literal of many MB) is bulk-loaded from bytes:
#: Oxigraph's streaming N-Triples reader stops at lines over 16 MiB, its
#: in-memory one does not.
DIRECT_CHARS = 8_000_000
#: An in-memory store's bulk loader holds the GIL while it reads from a Python
#: stream, so parse-and-map could not run beside it (a 100k-instance load took
#: CPU = wall, 5.3-6.2 s); from bytes it releases the GIL. So an in-memory load
#: gives one loader thread batches of this many characters as bytes (3.5-4.1 s,
#: measured alternating in one run; two such threads contend: 4.8-5.2 s). On
#: disk, streaming and bytes measured the same, and streaming keeps less text.
MEMORY_BATCH_CHARS = 4_000_000
#: measured costs per quad (µs of CPU time) of deleting a graph's quads (predicate by
#: predicate: 14-15 s for 1.36M quads beside 4M) and of copying a quad into a rebuilt
#: database; they choose how a graph is removed
DELETE_COST, REBUILD_COST = 11.0, 10.0
#: quads a delete transaction removes (30k to 250k measured the same; memory grows with it)
DELETE_BATCH = 100_000
#: deleted quads after which batched deletes flush RocksDB's memory tables (between rounds of
#: deletes, see GraphStore._flush). Unflushed, the
#: tombstones stay in memory: unloading a real 200k-instance program (2.7M quads) beside two
#: others peaked at 1,677 MB (37.8 s); flushed every 500k, 627 MB (34.3 s); after every
#: 100k-quad batch, 467 MB but 57.9 s (measured in one run)
FLUSH_DELETES = 500_000
#: an unload or a replacement that deleted compacts the database once the quads deleted since its
#: last compaction reach this share of the quads it holds (:meth:`GraphStore._settle`). A
#: compaction rewrites the whole database, so compacting at every unload made an unload cost its
#: deletes (about one load of the program) plus a share that grows with the store: 1.51x a load
#: beside three programs of its size (21.1 s against 14.0; the deletes 13.2 s), about 2.4 loads
#: beside ten. Deleted quads wait on disk as their data plus tombstones in six indexes: measured
#: 280 (100k instances) to 460 (1M) bytes each, where a live quad takes 170-310 bytes compacted;
#: at 0.5 a store of three 1M-instance programs took 10,830 MB after one was unloaded, 2.36 times
#: the 4,589 MB it took compacted (63.5 s). At 0.35 the store stays within about twice its
#: compacted size by the worst of those figures (1 + 2.7 * 0.35), and a compaction costs per
#: deleted quad at most 1.4-1.6 µs * (1 + 0.35) / 0.35 = 5.4-6 µs over time, against 10-12 µs a
#: quad for the deletes and a load: unloads cost about 1.5 (100k) to 1.7 (1M) loads on average,
#: whatever the store's size
COMPACT_AT = 0.35
#: the file in a store directory that counts the quads deleted since ``work/`` was last compacted
DELETED_QUADS = "deleted-quads"
#: quads per bulk_extend call of a rebuild (the bulk loader's memory grows with a call). Measured,
#: compacting a store of four real 100k-instance programs (5.46M quads), alternating: 1M a call,
#: 77-82 s wall / 87-93 s CPU, 864-918 MB peak; 250k, 74-76 s / 104-106 s, 392-414 MB. Two threads
#: copying graphs side by side gain nothing (the copy holds the GIL: 70 s, 100 s CPU), and one
#: N-Quads dump bulk-loaded in one call (the only text route: Oxigraph renames blank nodes per
#: parse, so the text cannot be split) took 52-70 s at 1.25-1.87 GB
REBUILD_BATCH = 250_000
#: a replacement beside other programs writes only what changed (see
#: GraphStore._replace_by_difference). The new version is staged in a store in memory when the
#: old one has at most this many quads (a 100k-instance program has 1.3-1.4M with its derived
#: layer), else in a store on disk in the scratch directory. In memory it is the peak of the
#: whole replacement: 646-648 MB for 1.26-1.36M quads, 1,150 MB for 2.72M of a real
#: 200k-instance program (27.7 s, where deleting, before FLUSH_DELETES, and loading took 59.3 s
#: and 1,871 MB; measured), so this bound keeps it under the load's 1.5 GB; on disk it costs
#: what loading into an empty store costs, in a load's memory
STAGE_IN_MEMORY_QUADS = 3_000_000
#: bytes of one graph's old N-Triples lines compared at a time: a larger dump is first split
#: into parts by a hash of each line (the lines in a set take about 1.5 times their size). The
#: deletes of one part run beside the comparison of the next (:class:`_Deleter`), their memory
#: tables beside its set: at 256 MiB a 1M-instance re-load peaked at 1,466 MB
COMPARE_BYTES = 128 << 20
#: quads per bulk call when a replacement by difference inserts what changed
INSERT_BATCH = 250_000
#: quads that :meth:`GraphStore.add_quads` writes in one transaction (more go through the bulk
#: loader: one bulk call costs about 0.1 s whatever its size, a transaction 4 µs a quad)
TRANSACTION_QUADS = 25_000
#: quads per DELETE DATA request of a replacement by difference
DELETE_LINES = 20_000
_LOCK_POLL = 0.2


def default_store_path() -> Path:
    return Path(os.environ.get(STORE_ENV) or DEFAULT_STORE)


@dataclass(frozen=True)
class Companion:
    """Text for a companion graph of a load (its derived layer), met among the load's chunks.

    A companion chunk is loaded where its graph is written now (a staging graph
    during an in-memory or remote replacement), so a loader can write the
    companion while it streams the main graph instead of keeping it for later.
    """

    graph: str
    text: str


@dataclass(frozen=True)
class Shadow:
    """Lines of a companion graph that the load writes later as quads (``before_commit``), met
    among the load's chunks as text whose blank nodes are named as in the main graph's chunks.

    A store does not load them: a blank node cannot be named across documents, so the load
    writes those quads itself. A replacement compares them, with the rest of the load's text,
    against the version in the store (:meth:`GraphStore._stage`).
    """

    graph: str
    text: str


Chunk = str | Companion | Shadow


class Store(Protocol):
    """What loading, export, info and queries need of a store: the embedded
    :class:`GraphStore` or a :class:`~stepnc_graph.store.remote.RemoteStore`."""

    path: Path | None
    last_removal: str | None

    def replace_graph(self, graph: str, chunks: Iterable[Chunk],
                      before_commit: Callable[[Callable[[str], str]], None] | None = None,
                      companions: Sequence[str] = ()) -> None: ...

    def remove_graph(self, graph: str, companions: Sequence[str] = (), compact: bool = False) -> bool: ...

    def add_ntriples(self, graph: str, text: str, bulk: bool = False) -> None: ...

    def add_turtle(self, graph: str, text: str) -> None: ...

    def update(self, sparql: str) -> None: ...

    def graphs(self) -> list[str]: ...

    def all_graphs(self) -> list[str]: ...

    def has_graph(self, graph: str) -> bool: ...

    def query(self, sparql: str, **kwargs: Any) -> Any: ...

    def count(self, graph: str | None = None) -> int: ...

    def quads(self, graph: str | None = None) -> Iterator[ox.Quad]: ...

    def close(self) -> None: ...

    def __enter__(self) -> Any: ...

    def __exit__(self, *exc: object) -> None: ...


class StoreError(Exception):
    """A store directory that cannot be used (not a store, newer format, missing, not writable)."""


@dataclass(frozen=True)
class Writer:
    """Who holds a store's writer lock, as it wrote it in ``write.lock``."""

    pid: int | None
    command: str
    since: str

    def __str__(self) -> str:
        who = f"pid {self.pid}" if self.pid else "another process"
        return f"{who}{': ' + self.command if self.command else ''}{', since ' + self.since if self.since else ''}"


class StoreWriteError(StoreError, OSError):
    """A write that the store's own files refused (a full disk, a read-only one), rolled back: a
    :class:`StoreError` that names the store, and still the ``OSError`` it was (``errno``)."""


class StoreBusy(StoreError):
    """Another process is writing to the store."""

    def __init__(self, path: Path, writer: Writer) -> None:
        super().__init__(f"{path} is being written by {writer}; try again when it is done, or wait for it "
                         f"(--wait)")
        self.writer = writer


class _ChunkStream(io.RawIOBase):
    """A binary file over an iterator of encoded chunks, for Oxigraph's streaming loader."""

    def __init__(self, chunks: Iterable[bytes]) -> None:
        self._chunks: Iterator[bytes] = iter(chunks)
        self._buffer = memoryview(b"")

    def readable(self) -> bool:
        return True

    def readinto(self, target: Any) -> int:
        while not self._buffer:
            chunk = next(self._chunks, None)
            if chunk is None:
                return 0
            self._buffer = memoryview(chunk)
        n = min(len(target), len(self._buffer))
        target[:n] = self._buffer[:n]
        self._buffer = self._buffer[n:]
        return n


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _clone(source: Path, target: Path) -> None:
    """A writable copy of an Oxigraph checkpoint: SST files hard-linked (RocksDB never
    changes one in place), the small bookkeeping files copied."""
    target.mkdir()
    for f in source.iterdir():
        if f.suffix == ".sst":
            os.link(f, target / f.name)
        else:
            shutil.copy2(f, target / f.name)


class _Locks:
    """The store's file locks (``flock``: released by the kernel when a process dies)."""

    @staticmethod
    def try_lock(path: Path, shared: bool) -> int | None:
        """An open descriptor holding the lock on ``path``, or None if it is held elsewhere.

        A reader of a store it cannot write (a read-only file system: an archived store; or no
        write permission) opens the lock file read-only, which ``flock`` allows. On a read-only
        file system no writer can delete a generation, so when even the lock file is missing
        a shared lock on the store directory stands for it."""
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            if not shared or e.errno not in (errno.EROFS, errno.EACCES, errno.EPERM):
                raise
            try:
                fd = os.open(path, os.O_RDONLY)
            except FileNotFoundError:
                if e.errno != errno.EROFS:
                    raise
                fd = os.open(path.parent, os.O_RDONLY)
        try:
            fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return None
        return fd

    @staticmethod
    def release(fd: int | None) -> None:
        if fd is not None:
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)


class GraphStore:
    """Named graphs in an Oxigraph store. ``path=None`` is a throw-away in-memory store.

    On disk, a store opened for writing (the default) holds the writer's lock
    until :meth:`close`; ``readonly=True`` opens the published state for
    reading, never blocks and never changes anything. ``create=False`` refuses
    a directory that is not a store yet (readers never create). ``wait`` makes a
    writer wait for the lock (``True``, or a number of seconds) instead of
    raising :class:`StoreBusy`; ``on_wait(writer)`` is called once before waiting.
    """

    def __init__(self, path: Path | str | None = None, *, readonly: bool = False, create: bool = True,
                 wait: bool | float = False, on_wait: Callable[[Writer], None] | None = None) -> None:
        self.path = Path(path) if path is not None else None
        self.readonly = readonly
        self._write_fd: int | None = None
        self._read_fd: int | None = None
        self._store: ox.Store | None = None
        self._closed_because: str | None = None  # why _db refuses use (a rollback that could not reopen)
        self.generation: str | None = None
        #: how the last graph removal was done on disk: "delete" or "rebuild" (for tests and benchmarks)
        self.last_removal: str | None = None
        #: what the last replacement by difference wrote: quads deleted and inserted (and of
        #: these, with a blank node), blank nodes of the new version that kept the old version's
        #: node (see _replace_by_difference)
        self.last_difference: dict[str, int] = {}
        #: whether the last unload or replacement compacted the database (see _settle)
        self.compacted = False
        self._deleted_after: int | None = None  # deleted_quads once this write commits (see _settle)
        self._deletes_logged = False  # work/'s write-ahead log holds batched deletes (see _commit)
        self._parked: ox.Store | None = None  # the database on disk while a replacement is staged
        self._tee: _Tee | None = None  # the text a load writes (see _Tee)
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
        self._check_directory(create and not readonly)
        try:
            if readonly:
                self._open_reader()
            else:
                self._open_writer(wait, on_wait)
        except OSError as e:
            self.close()
            if e.errno == errno.EROFS:
                raise StoreError(f"cannot write to the store in {self.path}: it is on a read-only file system (info, "
                                 "export, query and validate can still read it)") from None
            raise StoreError(f"cannot open the store in {self.path}: {e.strerror or e}") from None
        except BaseException:
            self.close()
            raise

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
        lock = self._file("write.lock")
        fd = _Locks.try_lock(lock, shared=False)
        if fd is None:
            if not wait:
                raise StoreBusy(self.path, self._writer())  # type: ignore[arg-type]
            if on_wait is not None:
                on_wait(self._writer())
            deadline = None if wait is True else time.monotonic() + float(wait)
            while fd is None:
                if deadline is not None and time.monotonic() > deadline:
                    raise StoreBusy(self.path, self._writer())  # type: ignore[arg-type]
                time.sleep(_LOCK_POLL)
                fd = _Locks.try_lock(lock, shared=False)
        self._write_fd = fd
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps({"pid": os.getpid(), "command": _command_line(),
                                  "since": time.strftime("%Y-%m-%d %H:%M:%S")}).encode(), 0)
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

    def _open_reader(self) -> None:
        if (self._file("oxigraph")).exists():  # format 1: needs the writer to migrate it
            with GraphStore(self.path, create=False):
                pass
        for _ in range(100):
            generation = self._current()
            if generation is None:
                raise StoreError(f"the store in {self.path} is being created; try again")
            fd = _Locks.try_lock(self._file(generation + ".lock"), shared=True)
            if fd is not None and self._current() == generation and self._file(generation).is_dir():
                self._read_fd, self.generation = fd, generation
                self._store = ox.Store.read_only(str(self._file(generation)))
                return
            _Locks.release(fd)
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
        _clone(self._file(current), work)
        stamp.write_text(current)
        dirty.unlink(missing_ok=True)

    # -- generations ----------------------------------------------------------------------

    def _begin(self) -> None:
        """Mark ``work/`` as possibly different from the published generation."""
        if self.path is None:
            return
        if self.readonly:
            raise StoreError(f"the store in {self.path} was opened read-only")
        dirty = self._file("work.dirty")
        try:
            if not dirty.exists():
                dirty.write_text("")
                _fsync_dir(self.path)
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
        _fsync_dir(self.path)
        self.generation = name
        self._file("work.generation").write_text(name)
        self._file("work.dirty").unlink(missing_ok=True)

    def serving(self) -> Path:
        """Hand the writer's database to another process (``serve --writable``): it is closed
        here and marked as being served; :meth:`served` takes it back and publishes it."""
        if self.path is None or self.readonly:
            raise StoreError("only an on-disk store opened for writing can be served writable")
        self._close_db()
        self._file("work.serving").write_text(str(os.getpid()))
        _fsync_dir(self.path)
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
        or a replacement runs once they reach :data:`COMPACT_AT` of the store."""
        if self.path is None:
            return 0
        try:
            return int(self._file(DELETED_QUADS).read_text())
        except (OSError, ValueError):
            return 0

    def _settle(self, deleted: int, held: int, compact: bool = False) -> None:
        """Count ``deleted`` quads against the database, which holds about ``held`` quads, and
        compact it (``optimize``: the space of deleted quads comes back) when the quads deleted
        since its last compaction reach :data:`COMPACT_AT` of ``held``, or when ``compact``
        asks for it. Not at every unload: a compaction rewrites the whole database, so its cost
        grows with the store, not with what was deleted (see :data:`COMPACT_AT`)."""
        pending = self.deleted_quads + deleted
        self.compacted = compact or pending >= COMPACT_AT * max(held, 1)
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
            fd = _Locks.try_lock(self._file(name + ".lock"), shared=False)
            if fd is None:
                continue  # a reader still reads it; a later writer deletes it
            try:
                shutil.rmtree(entry, ignore_errors=True)
                self._file(name + ".lock").unlink(missing_ok=True)
            finally:
                _Locks.release(fd)

    # -- closing ------------------------------------------------------------------------------

    def _close_db(self) -> None:
        if self._store is not None:
            if self.path is not None and not self.readonly:
                self._store.flush()
            self._store = None
            if self.path is not None:  # an in-memory store has no files or lock to release
                gc.collect()  # pyoxigraph releases the database (and its RocksDB lock) when collected

    def close(self) -> None:
        """Release the database and the store's locks. Idempotent."""
        self._close_db()
        _Locks.release(self._read_fd)
        _Locks.release(self._write_fd)
        self._read_fd = self._write_fd = None

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
        if self.path is None:
            self._replace_in_memory(graph, chunks, before_commit, companions)
            return
        self._begin()
        self.compacted = False
        kept = self._usable_kept()
        self._touch([graph, *companions, VOCABULARY_GRAPH])
        try:
            how, present, removed, held = self._removal([graph, *companions], kept)
            if how == "delete":
                deleted = self._replace_by_difference(graph, chunks, before_commit, companions, kept,
                                                      in_memory=removed <= STAGE_IN_MEMORY_QUADS)
                self._settle(deleted, held)
            else:
                self._remove(how, present)
                self._load_kept(graph, chunks, before_commit, [graph, *companions])
            self._commit()
        except BaseException as exc:
            self._failed(exc)
            raise

    def remove_graph(self, graph: str, companions: Sequence[str] = (), compact: bool = False) -> bool:
        """Remove ``graph`` and its ``companions``; False if ``graph`` was not there.

        Deleted quads keep their disk space until the database is compacted: beside other
        programs that happens once enough was deleted (:meth:`_settle`), or now with
        ``compact``. Removed by a rebuild, the space comes back at once. Refuses what
        :meth:`replace_graph` refuses."""
        refuse_strangers(graph, companions)
        if not self._db.contains_named_graph(ox.NamedNode(graph)):
            return False
        if self.path is None:
            for name in (graph, *companions):
                self._db.remove_graph(ox.NamedNode(name))
            return True
        self._begin()
        self.compacted = False
        kept = self._usable_kept()
        self._touch([graph, *companions])
        try:
            how, present, removed, held = self._removal([graph, *companions], kept)
            self._remove(how, present)
            if how == "delete":
                self._settle(removed, held - removed, compact)
            self._commit()
        except BaseException as exc:
            self._failed(exc)
            raise
        return True

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
        self._tee = tee = _Tee(names, kept=self._kept.writing(names))
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

    def _quads_about(self, graphs: Sequence[str] | None, kept: dict[str, KeptText]) -> int:
        """About the quads of ``graphs`` (None: of the database), for choosing how to remove and
        when to compact: a graph's kept text gives its count (unless the text repeated a line),
        the others are counted (Oxigraph counts by scanning: 5.9 s for 40.8M quads, 2 s for a
        program graph of 8M)."""
        if graphs is not None:
            return sum(kept[g].lines if g in kept else self.count(g) for g in graphs)
        counted = self._count_in(self._db, None) + sum(self.count(g) for g in self.all_graphs() if g not in kept)
        return counted + sum(k.lines for g, k in kept.items() if self.has_graph(g))

    def _quads_in(self, graphs: Sequence[str]) -> int:
        return sum(self.count(g) for g in graphs if self.has_graph(g))

    def _removal(self, graphs: Sequence[str],
                 kept: dict[str, KeptText]) -> tuple[str | None, list[str], int, int]:
        """How removing ``graphs`` costs less (see the module docstring): "rebuild", "delete",
        or None when none of them is there; with the ones present, their quads and the
        database's (about: see :meth:`_quads_about`)."""
        present = [g for g in graphs if self.has_graph(g)]
        if not present:
            return None, [], 0, 0
        removed, held = self._quads_about(present, kept), self._quads_about(None, kept)
        how = "rebuild" if (held - removed) * REBUILD_COST < removed * DELETE_COST else "delete"
        return how, present, removed, held

    def _remove(self, how: str | None, present: list[str]) -> None:
        """Remove the graphs ``present`` the way :meth:`_removal` chose."""
        if how is None:
            return
        self.last_removal = how
        if how == "rebuild":
            self._rebuild_without(set(present))
        else:
            self._delete_in_batches(present)

    def _replace_by_difference(self, graph: str, chunks: Iterable[Chunk],
                               before_commit: Callable[[Callable[[str], str]], None] | None,
                               companions: Sequence[str], kept: dict[str, KeptText],
                               in_memory: bool = True) -> int:
        """Replace ``graph`` and its companions by writing only the quads that changed; returns
        how many quads were deleted.

        Deleting costs Oxigraph more than loading does (see the module docstring), so a
        replacement that deletes the old version and loads the new one costs two to three loads
        beside other programs.
        Here the new version is loaded and completed (``before_commit``) in a store of its own
        (in memory, or on disk in the scratch directory when ``in_memory`` is false, see
        :data:`STAGE_IN_MEMORY_QUADS`), then each graph is compared with the one on disk as
        N-Triples lines (the old version from the text its load kept, ``kept``, see
        :meth:`_old_from_kept`; else dumped), and only the lines that changed are deleted and
        inserted. Blank nodes
        (list cells, typed values), which no two loads name alike, are first matched between the
        versions by their place under the instance that owns them (:class:`_BlankMatch`), so an
        unchanged list compares equal and keeps its nodes. A re-load of the same file then
        changes only its load's provenance. If the counts do not come out as the staged ones,
        the graphs are dropped and loaded whole from the staged version: never a wrong graph.
        The texts go through files in ``DIR/difference/`` (removed after, or by the next
        writer's recovery). :attr:`last_difference` counts what was written.

        The loader rewrites the vocabulary graph only when it is stale; the staged store gets
        the vocabulary's own description from disk, so it is compared only when rewritten.
        """
        scratch = self._file("difference")
        shutil.rmtree(scratch, ignore_errors=True)
        scratch.mkdir()
        try:
            new, old, dumped = self._stage(graph, chunks, before_commit, [graph, *companions], scratch, in_memory,
                                           kept)
            _give_back_freed_memory()  # the staged store was the peak of an in-memory replacement
            shutil.rmtree(scratch / "staged", ignore_errors=True)
            self.last_removal = "difference"
            match = _BlankMatch(old[graph], new[graph])
            staged_counts = self._apply_difference(old, new, match, scratch)
            self.last_difference["staged in memory"] = int(in_memory)
            self.last_difference["new version dumped"] = int(dumped)
            deleted = self.last_difference["deleted"]

            def adds_up() -> bool:
                return all(staged_counts[n] == self.count(n) for n in new)

            if not adds_up():
                self.last_removal = "difference, then delete"
                present = [n for n in new if self.has_graph(n)]
                deleted += self._quads_in(present)
                self._delete_in_batches(present)
                self._insert(self._relabelled(new, match, scratch / "whole.nq"))
                if not adds_up():  # rolled back: never a wrong graph
                    raise StoreError(f"replacing {graph} did not add up (the new version's quads differ from "
                                     "what was staged); the store is unchanged")
            return deleted
        finally:
            shutil.rmtree(scratch, ignore_errors=True)

    def _stage(self, graph: str, chunks: Iterable[Chunk], before_commit: Callable[[Callable[[str], str]], None] | None,
               names: list[str], scratch: Path, in_memory: bool,
               kept: dict[str, KeptText]) -> tuple[dict[str, Path | None], dict[str, Path | None], bool]:
        """Load the new version of ``graph`` into a store of its own (in memory, or in
        ``scratch/staged``) and complete it there, while the old version of the graphs ``names``
        is written out (from the text its load kept, :meth:`_old_from_kept`, or dumped). Returns the N-Triples files of the new and of the old version, graph by
        graph (None: no such graph; the vocabulary graph is among them when the load rewrote it),
        and whether the new version was dumped (see below). The staged store is dropped on return.

        The new version's files are the text the load wrote (:class:`_Tee`: its chunks, its
        :class:`Shadow` lines, what ``before_commit`` added as N-Triples), when each holds as
        many lines as the staged store holds quads in that graph -- so no line was lost,
        repeated or merged with another. Else they are dumps of the staged store, which cost
        about as much as the dumps of the old version (Oxigraph decodes every term: 5-8 µs a
        quad, measured on a 1M-instance program's 13.6M quads).
        """
        staged = ox.Store() if in_memory else ox.Store(str(scratch / "staged"))
        vocabulary = ox.NamedNode(VOCABULARY_GRAPH)
        staged.extend(self._db.quads_for_pattern(vocabulary, None, None, vocabulary))
        seeded = len(staged)
        old: dict[str, Path | None] = {}
        errors: list[BaseException] = []
        from_kept: list[str] = []

        def old_version(k: int) -> Path | None:
            name, path = names[k], scratch / f"old{k}.nt"
            try:
                if not self._disk.contains_named_graph(ox.NamedNode(name)):
                    return None
                if name in kept and self._old_from_kept(name, kept[name], path):
                    from_kept.append(name)
                    return path
                return self._dump_graph(self._disk, name, path)
            except BaseException as exc:  # a graph's failure is held by its future, maybe never raised
                traceback.clear_frames(exc.__traceback__)  # its frames' locals hold the database
                raise

        def dump_old() -> None:
            """The old version is written out while the new one is staged (from its kept text, or
            dumped: Oxigraph's dump releases the GIL, 4 s of a 100k-instance program's 1.3M quads)."""
            try:
                with ThreadPoolExecutor(len(names)) as pool:  # a dump is one thread: the graphs side by side
                    old.update(zip(names, pool.map(old_version, range(len(names))), strict=True))
            except BaseException as exc:  # noqa: BLE001 -- raised by the replacement below
                traceback.clear_frames(exc.__traceback__)  # its frames' locals hold the database
                errors.append(exc)

        # The database on disk is parked in an attribute, never in a local of this frame: a
        # failure's traceback must not keep it open, or the rollback could not reopen it.
        self._parked, self._store = self._store, staged
        self._tee = tee = _Tee(names, scratch, self._kept.writing(names))
        dumping = threading.Thread(target=dump_old, daemon=True)
        dumping.start()
        try:
            try:
                self._bulk_load(graph, chunks, in_memory=in_memory)
                if before_commit is not None:
                    before_commit(lambda name: name)
            finally:
                self._tee = None
                tee.close()
                dumping.join()
                self._store, self._parked = self._parked, None
            if errors:
                raise errors[0]
            teed = tee.new_version(staged)
        except BaseException:
            tee.discard()
            raise
        self.last_difference = {"old version kept": len(from_kept)}
        if teed is None:
            tee.discard()
            for path in tee.paths.values():
                path.unlink(missing_ok=True)
        else:
            self._kept_written.update(tee.keep())
        to_dump = names if teed is None else []  # and the vocabulary, if the load rewrote it
        if staged.contains_named_graph(vocabulary) and self._count_in(staged, VOCABULARY_GRAPH) != seeded:
            to_dump = [*to_dump, VOCABULARY_GRAPH]
            old[VOCABULARY_GRAPH] = self._dump_graph(self._db, VOCABULARY_GRAPH, scratch / "old-vocabulary.nt")
        _give_back_freed_memory()  # what completing the graph took, before its dump
        new = dict(teed or {})
        with ThreadPoolExecutor(LOAD_THREADS) as pool:  # the dumps release the GIL: the graphs side by side
            paths = pool.map(lambda k: self._dump_graph(staged, to_dump[k], scratch / f"staged{k}.nt"),
                             range(len(to_dump)))
            new.update(zip(to_dump, paths, strict=True))
        return new, old, teed is None

    def _old_from_kept(self, name: str, kept: KeptText, path: Path) -> bool:
        """Write graph ``name`` of the database to ``path`` as N-Triples from the text its load
        kept (see :mod:`stepnc_graph.store.kept`): the lines without blank node as kept, the others
        read from the database, predicate by predicate (their blank nodes are named there as the
        bulk loader named them: 6 s for a 1M-instance program's 1.66M such lines, where the dumps
        of its two graphs take about 120 s of CPU). False, and nothing to use, when the file is
        damaged or the line counts differ from the database's."""
        db, node = self._disk, ox.NamedNode(name)
        blank = path.with_name(path.stem + "-blank.nt")
        try:
            with open(path, "wb", buffering=1 << 20) as out:
                found = read_without_blank_nodes(self._kept.path(kept), out)
                if found.lines + found.blank != kept.lines:
                    return False
                read = 0
                for predicate in sorted(found.predicates):
                    p = predicate.decode("utf-8")
                    triples = db.query(f"CONSTRUCT {{ ?s {p} ?o }} WHERE {{ GRAPH {node} {{ ?s {p} ?o "
                                       f"FILTER(isBlank(?s) || isBlank(?o)) }} }}")
                    assert isinstance(triples, ox.QueryTriples)
                    # Into a file by Oxigraph itself: as bytes the text of one predicate was
                    # held twice (150 MB at 1M instances); into a Python writer, every write
                    # waits for the interpreter (94 s instead of 2 beside a busy thread).
                    triples.serialize(str(blank), ox.RdfFormat.N_TRIPLES)
                    del triples  # a query's result holds the database open
                    read += _append(blank, out)
        except (OSError, EOFError, zlib.error, UnicodeDecodeError, SyntaxError):
            return False
        finally:
            blank.unlink(missing_ok=True)
        return read == found.blank and found.lines + read == self._count_in(db, name)

    @staticmethod
    def _relabelled(new: dict[str, Path | None], match: _BlankMatch, path: Path) -> Path:
        """The files ``new`` as one N-Quads file ``path``, blank nodes named by ``match`` (the
        load's own labels are not unique in the store, see :meth:`_BlankMatch.relabel`)."""
        with open(path, "wb", buffering=1 << 20) as out:
            for name, lines in new.items():
                suffix = b" <" + name.encode("utf-8") + b"> .\n"
                for line in _lines(lines):
                    out.write(match.relabel(line)[:-3] + suffix)
        return path

    @staticmethod
    def _dump_graph(store: ox.Store, name: str, path: Path) -> Path | None:
        """Write graph ``name`` of ``store`` to ``path`` as N-Triples; None if it has no such graph."""
        node = ox.NamedNode(name)
        if not store.contains_named_graph(node):
            return None
        store.dump(str(path), ox.RdfFormat.N_TRIPLES, from_graph=node)
        return path

    @staticmethod
    def _count_in(store: ox.Store, graph: str | None) -> int:
        """Quads in ``graph`` of ``store`` (None: its default graph)."""
        pattern = "?s ?p ?o" if graph is None else f"GRAPH {ox.NamedNode(graph)} {{ ?s ?p ?o }}"
        rows = store.query(f"SELECT (COUNT(*) AS ?n) WHERE {{ {pattern} }}")
        assert isinstance(rows, ox.QuerySolutions)
        [row] = list(rows)
        return int(row[0].value)

    def _apply_difference(self, old: dict[str, Path | None], new: dict[str, Path | None], match: _BlankMatch,
                          scratch: Path) -> dict[str, int]:
        """Make each graph on disk, dumped to the N-Triples file ``old`` gives for it, hold the
        file ``new`` gives for it (None: no such graph), blank nodes of the new version named
        as ``match`` gives (see :meth:`_replace_by_difference`). One graph at a time, one part
        of it at a time (:func:`_compared_parts`): its old lines in a set, the new ones read one
        at a time; the lines to delete go to a file per part, deleted by a :class:`_Deleter`
        while the next part is compared; the lines to insert to one file, inserted once all
        is deleted. Returns how many lines each new file has (the quads each graph must end
        with)."""
        deleted = inserted = blank = 0
        lines: dict[str, int] = {}
        inserts = scratch / "insert.nq"
        deleter = _Deleter(self)
        try:
            with open(inserts, "wb") as out:
                for k, (name, path) in enumerate(new.items()):
                    node = ox.NamedNode(name)
                    suffix = b" <" + name.encode("utf-8") + b"> .\n"
                    count = 0
                    parts = _compared_parts(old.get(name), path, match.relabel, scratch / f"part{k}")
                    for n, (old_part, new_lines) in enumerate(parts):
                        unmatched = _line_set(old_part)  # old lines no new line has matched yet
                        for line in new_lines:
                            count += 1
                            if line in unmatched:
                                unmatched.remove(line)  # a graph's lines are distinct, so are relabelled ones
                            else:
                                out.write(line[:-3] + suffix)  # each line ends " .\n"
                                inserted += 1
                                blank += _has_blank(line)
                        deleted += len(unmatched)
                        gone = scratch / f"gone{k}-{n}.nt"
                        with open(gone, "wb") as gone_out:
                            gone_out.writelines(unmatched)
                        del unmatched
                        deleter.delete(node, gone)
                    lines[name] = count
                    deleter.settle_graph(node, present=path is not None)
            deleter.finish()
        finally:
            deleter.close()
        self._insert(inserts)
        self._deletes_logged = True
        self.last_difference.update({"deleted": deleted, "inserted": inserted, "inserted with a blank node": blank,
                                     "blank nodes kept": match.kept})
        return lines

    def _delete_lines(self, node: ox.NamedNode, path: Path, unflushed: int = 0) -> int:
        """Delete the N-Triples lines of the file ``path`` (as Oxigraph dumped them) from graph
        ``node``, :data:`DELETE_LINES` at a time: ground ones by ``DELETE DATA``, the ones with a
        blank node (which SPARQL cannot name) parsed with their labels kept and removed one by
        one. The memory tables are flushed after every :data:`FLUSH_DELETES` lines, as batched
        deletes do between rounds (their tombstones stay in memory until then), counting the
        ``unflushed`` lines deleted before; returns the count left. The caller sees to it that
        no other thread deletes meanwhile."""
        with open(path, "rb") as fh:
            while batch := list(itertools.islice(fh, DELETE_LINES)):
                if unflushed >= FLUSH_DELETES:
                    self._flush()
                    unflushed = 0
                unflushed += len(batch)
                ground: list[bytes] = []
                blank: list[bytes] = []
                for line in batch:
                    (blank if _has_blank(line) else ground).append(line)
                if ground:
                    self._db.update(f"DELETE DATA {{ GRAPH {node} {{ {b''.join(ground).decode('utf-8')} }} }}")
                for triple in ox.parse(b"".join(blank), format=ox.RdfFormat.N_TRIPLES):
                    self._db.remove(ox.Quad(triple.subject, triple.predicate, triple.object, node))
        return unflushed

    def _insert(self, path: Path, graph: str | None = None) -> None:
        """Add the N-Quads file ``path`` (N-Triples into ``graph`` when one is given), its blank
        node labels kept (they are the staged store's random 128-bit ids, so a blank node that two
        graphs share -- the derived layer points at the program's list cells -- stays one node
        across calls and files), in bulk calls of :data:`INSERT_BATCH` quads."""
        if graph is None:
            quads = iter(ox.parse(path=str(path), format=ox.RdfFormat.N_QUADS))
        else:
            node = ox.NamedNode(graph)
            quads = (ox.Quad(t.subject, t.predicate, t.object, node)
                     for t in ox.parse(path=str(path), format=ox.RdfFormat.N_TRIPLES))
        for _ in _extend_in_calls(self._db, quads, INSERT_BATCH):
            pass

    @property
    def _disk(self) -> ox.Store:
        """The database on disk, also while a replacement is staged in memory."""
        return self._parked if self._parked is not None else self._db

    def _delete_in_batches(self, graphs: Sequence[str]) -> None:
        """Delete the quads of ``graphs`` (a program graph and its companions) in transactions of
        bounded size (flat memory), predicate by predicate, :data:`DELETE_BATCH` quads a
        transaction, on :data:`LOAD_THREADS` threads, the largest predicates first (balanced
        threads).

        Why by predicate: a batch's scan of one predicate's quads in a graph is one range of
        an index, and it meets only the tombstones of the quads of that predicate deleted
        before it. "The first n quads of the graph" again and again walks over the tombstones
        of every quad deleted so far (17.6 µs a quad, 1M quads beside 2M), and deleting by
        lists of IRI subjects seeks each subject's quads (a real 100k-instance program beside
        three: 17.7 s of wall, 32 s of CPU time for its 1.36M quads; by predicate 8.5-9.8 s and
        14-15 s; measured alternating in one run). It also takes blank nodes' quads, which
        SPARQL cannot name, with the rest.
        """
        nodes = [ox.NamedNode(g) for g in graphs]
        work: list[tuple[ox.NamedNode, str, int]] = []
        for node in nodes:
            counts = self._db.query(f"SELECT ?p (COUNT(*) AS ?n) WHERE {{ GRAPH {node} {{ ?s ?p ?o }} }} GROUP BY ?p")
            work += [(node, str(row[0]), int(row[1].value)) for row in counts]  # type: ignore[union-attr]
            del counts  # a query's rows hold the database open
        with ThreadPoolExecutor(LOAD_THREADS) as pool:
            for k, part in enumerate(_delete_rounds(work, FLUSH_DELETES, LOAD_THREADS)):
                if k:
                    self._flush()
                list(pool.map(self._delete_predicate, part))
        self._deletes_logged = True
        for node in nodes:
            self._db.remove_graph(node)  # the name, and any quad added since the count

    def _flush(self) -> None:
        """Write the database's memory tables to disk, between two rounds of batched deletes.

        Never while a delete runs on another thread: RocksDB's manual flush then sometimes
        waits forever for a flush that is never scheduled (seen here in 4 of 20 runs of the
        batched-delete test, flushing from the deleting threads: background threads idle, the
        flushing one in ``DBImpl::WaitForFlushMemTables``)."""
        self._db.flush()

    def _delete_predicate(self, item: tuple[ox.NamedNode, str, int]) -> None:
        """Delete ``n`` quads of one predicate in one graph, :data:`DELETE_BATCH` a transaction."""
        node, predicate, n = item
        for done in range(0, n, DELETE_BATCH):
            self._db.update(f"DELETE {{ GRAPH {node} {{ ?s {predicate} ?o }} }} WHERE {{ {{ SELECT ?s ?o WHERE "
                            f"{{ GRAPH {node} {{ ?s {predicate} ?o }} }} LIMIT {min(DELETE_BATCH, n - done)} }} }}")

    def _rebuild_without(self, dropped: set[str], progress: Callable[[int, int], None] | None = None) -> None:
        """Replace ``work/`` by a fresh database holding every graph but ``dropped``.

        ``progress(done, total)`` is told the quads copied after each bulk call. On a failure
        (or an exception from ``progress``) no reference to either database stays in this
        frame, so the rollback can reopen ``work/``.
        """
        rebuild = self._file("rebuild")
        shutil.rmtree(rebuild, ignore_errors=True)
        fresh = ox.Store(str(rebuild))
        keep = [g for g in self._db.named_graphs() if not (isinstance(g, ox.NamedNode) and g.value in dropped)]
        total = len(self._db) - self._quads_in(sorted(dropped)) if progress else 0
        done = 0
        try:
            for g in [ox.DefaultGraph(), *keep]:
                for copied in self._copy_graph(fresh, g):
                    done += copied
                    if progress is not None:
                        progress(done, total)
            fresh.flush()
        except BaseException:
            del fresh
            raise
        del fresh
        self._close_db()
        shutil.rmtree(self._file("work"))
        rebuild.rename(self._file("work"))
        self._store = ox.Store(str(self._file("work")))
        self._deleted_after = 0  # a fresh database: nothing deleted in it

    def _copy_graph(self, fresh: ox.Store, graph: ox.NamedNode | ox.BlankNode | ox.DefaultGraph) -> Iterator[int]:
        """Copy ``graph`` into ``fresh``, yielding how many quads each bulk call copied. A
        generator, so that the iterator over the database lives in its frame only, not in the
        caller's."""
        yield from _extend_in_calls(fresh, iter(self._db.quads_for_pattern(None, None, None, graph)))
        if isinstance(graph, (ox.NamedNode, ox.BlankNode)):
            fresh.add_graph(graph)  # an empty named graph stays a graph

    def _bulk_load(self, graph: str, chunks: Iterable[Chunk],
                   target: Callable[[str], str] = lambda name: name, in_memory: bool | None = None) -> None:
        """Stream ``chunks`` into ``graph`` with one bulk loader per core.

        Measured on a 2-core machine: one ``bulk_load`` call ingests ~125k
        quads/s into a named graph on disk using one core; two concurrent calls
        on halves of the data reach ~230k quads/s. So the producer (this
        thread: parse and map) fills a bounded queue and ``LOAD_THREADS``
        threads each run a streaming ``bulk_load`` over it (pyoxigraph releases
        the GIL while loading; an in-memory store is fed differently, see
        :data:`MEMORY_BATCH_CHARS`). Chunks end at instance boundaries and blank-node
        labels are unique per load, so every thread's document is self-contained.
        A :class:`Companion` chunk is loaded on its own into ``target(its graph)``.
        """
        in_memory = self.path is None if in_memory is None else in_memory
        threads_n = 1 if in_memory else LOAD_THREADS  # see MEMORY_BATCH_CHARS
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
                    if type(item) is not bytes or len(item) > DIRECT_CHARS:
                        large.append(item)
                        return
                    used += len(item)
                    yield item

            try:
                while not ended:
                    large: list[bytes | tuple[str, bytes]] = []
                    if in_memory:
                        data = b"".join(pull(MEMORY_BATCH_CHARS, large))
                        if data:
                            self._db.bulk_load(data, ox.RdfFormat.N_TRIPLES, to_graph=main, lenient=True)
                    else:
                        stream = io.BufferedReader(_ChunkStream(pull(BATCH_CHARS, large)), 1 << 20)
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

    def update(self, sparql: str) -> None:
        """One SPARQL Update (one transaction); for writes inside a load's ``before_commit``
        (into the graphs of that load: outside a load, it may have changed any graph)."""
        self._touch_any_outside_a_write()
        self._db.update(sparql)

    def _touch_any_outside_a_write(self) -> None:
        if self._since is None:
            self._touch(None)

    def add_ntriples(self, graph: str, text: str, bulk: bool = False) -> None:
        """Add N-Triples to ``graph`` (for use inside ``before_commit``): in one transaction, or
        with ``bulk`` through Oxigraph's bulk loader (faster for many, not transactional: the load
        around it is)."""
        if self._tee is not None:
            self._tee.write(graph, text)
        self._touch([graph])
        if bulk or len(text) > DIRECT_CHARS:
            for piece in _line_pieces(text, BATCH_CHARS):  # the bulk loader's memory grows with a call
                self._db.bulk_load(piece.encode("utf-8"), ox.RdfFormat.N_TRIPLES, to_graph=ox.NamedNode(graph))
        else:
            self._db.load(text, ox.RdfFormat.N_TRIPLES, to_graph=ox.NamedNode(graph))

    def add_quads(self, quads: Iterable[ox.Quad]) -> int:
        """Add ``quads`` (for use inside ``before_commit``), pulled one at a time: up to
        :data:`TRANSACTION_QUADS` in one transaction, more through the bulk loader in calls of
        :data:`INSERT_BATCH` (a transaction holds all of its quads in memory, several times
        their size). Returns how many were added."""
        self._touch_any_outside_a_write()
        it = iter(quads)
        first = list(itertools.islice(it, TRANSACTION_QUADS + 1))
        if len(first) <= TRANSACTION_QUADS:
            self._db.extend(first)
            return len(first)
        return sum(_extend_in_calls(self._db, itertools.chain(first, it), INSERT_BATCH))

    def add_turtle(self, graph: str, text: str) -> None:
        """Add a Turtle document to ``graph`` (inside ``before_commit``, like :meth:`add_ntriples`):
        parsed by Oxigraph in one call, with no Python object per triple."""
        self._touch([graph])
        self._db.bulk_load(text.encode("utf-8"), ox.RdfFormat.TURTLE, to_graph=ox.NamedNode(graph))

    def compact(self, progress: Callable[[int, int], None] | None = None) -> None:
        """Rebuild the database from its graphs, as one atomic write (``stepnc-graph compact``).

        An unload beside other programs compacts RocksDB's tables (once enough was deleted,
        see :data:`COMPACT_AT`), but Oxigraph never deletes the strings (literals, IRIs) that
        only removed quads used (measured: a 100k-instance program unloaded beside three others
        left 1,200 MB on disk where a rebuilt store takes 945 MB), so a store whose programs come
        and go keeps growing. A rebuild keeps only what the graphs hold. It copies every quad
        (about 16 µs of CPU each), so it is a maintenance step, not part of every unload.
        ``progress(done, total)`` counts the quads copied. An in-memory store has nothing to give
        back.
        """
        if self.path is None:
            return
        self._begin()
        try:
            self._rebuild_without(set(), progress)
            self._db.optimize()  # the bulk loader's tables, merged now rather than beside the published ones
            self._commit()
        except BaseException as exc:
            self._failed(exc)
            raise

    def disk_bytes(self) -> int:
        """Bytes the store directory takes on disk (a file hard-linked into several generations
        counted once); 0 for an in-memory store."""
        return 0 if self.path is None else directory_bytes(self.path)

    # -- reading ------------------------------------------------------------------------

    def graphs(self) -> list[str]:
        """The loaded files' graphs (and graphs users or `link` added): not staging graphs, the
        vocabulary graph or a program's derived layer (see :func:`graph_layout`)."""
        return graph_layout(self).listed()

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
        return len(self._db) if graph is None else self._count_in(self._db, graph)

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
        next write (see :mod:`stepnc_graph.store.kept`)."""
        if not self.readonly:
            self._touch(None)
        return self._db

    def rdflib_dataset(self) -> Any:
        """An rdflib ``Dataset`` over the same data (oxrdflib), for rdflib/pySHACL users."""
        import rdflib
        from oxrdflib.store import OxigraphStore

        return rdflib.Dataset(store=OxigraphStore(store=self.oxigraph))


class _Deleter:
    """Deletes a replacement's old lines on a thread of its own, in the order given, while the
    caller compares the next part: the comparison is Python, which holds the interpreter,
    and Oxigraph's updates let go of it (measured: a 200k-line DELETE DATA took 1.2 s and a
    Python loop beside it ran at full speed). One thread, so that its flushes never run
    beside a delete (see :data:`FLUSH_DELETES`). The first error stops it and is raised by
    :meth:`finish`."""

    def __init__(self, store: GraphStore) -> None:
        self._store = store
        self._work: queue.Queue[Callable[[], None] | None] = queue.Queue()
        self._error: BaseException | None = None
        self._unflushed = 0
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while (task := self._work.get()) is not None:
            if self._error is None:
                try:
                    task()
                except BaseException as exc:  # noqa: BLE001 -- raised by finish()
                    traceback.clear_frames(exc.__traceback__)  # its frames' locals hold the database
                    self._error = exc

    def delete(self, node: ox.NamedNode, path: Path) -> None:
        """Delete the lines of the file ``path`` from graph ``node``, then remove the file."""
        def task() -> None:
            self._unflushed = self._store._delete_lines(node, path, self._unflushed)
            path.unlink()
        self._work.put(task)

    def settle_graph(self, node: ox.NamedNode, present: bool) -> None:
        """Once its lines are deleted: drop graph ``node`` if the new version has none, or
        make sure it is there (an empty graph stays a graph)."""
        def task() -> None:
            db = self._store._db
            if not present:
                db.remove_graph(node)
            elif not db.contains_named_graph(node):
                db.add_graph(node)
        self._work.put(task)

    def finish(self) -> None:
        """Wait for every delete; raise the first error."""
        self.close()
        if self._error is not None:
            raise self._error

    def close(self) -> None:
        if self._thread.is_alive():
            self._work.put(None)
            self._thread.join()


class _Tee:
    """The text a load writes into the graphs ``names``, as it goes by: for a replacement to
    compare (files in ``scratch``, see :meth:`GraphStore._stage`) and to keep for the next one
    (``kept``, see :mod:`stepnc_graph.store.kept`). Encoded once for both."""

    def __init__(self, names: Sequence[str], scratch: Path | None = None, kept: KeptWriting | None = None) -> None:
        self.paths = {} if scratch is None else {name: scratch / f"new{k}.nt" for k, name in enumerate(names)}
        self.lines = dict.fromkeys(names, 0)
        self._files = {name: open(path, "wb", buffering=1 << 20) for name, path in self.paths.items()}
        self._kept = kept

    def write(self, graph: str, text: str) -> None:
        """N-Triples lines written into ``graph`` (none kept for a graph not in ``names``)."""
        if graph in self.lines and text:
            self.write_bytes(graph, text.encode("utf-8"))

    def write_bytes(self, graph: str, data: bytes) -> None:
        """The same, encoded."""
        if graph not in self.lines or not data:
            return
        if data[-1] != 10:
            data += b"\n"
        self.lines[graph] += data.count(b"\n")
        if (out := self._files.get(graph)) is not None:
            out.write(data)
        if self._kept is not None:
            self._kept.write(graph, data)

    def close(self) -> None:
        for out in self._files.values():
            out.close()

    def keep(self) -> dict[str, KeptText]:
        """The kept texts, once compressed (see :class:`KeptWriting`)."""
        kept, self._kept = self._kept, None
        return {} if kept is None else kept.finish(self.lines)

    def discard(self) -> None:
        """Keep nothing: the load failed, or its text is not the new version."""
        kept, self._kept = self._kept, None
        if kept is not None:
            kept.discard()

    def new_version(self, staged: ox.Store) -> dict[str, Path | None] | None:
        """The files, graph by graph (None: the staged store has no such graph), if each has as
        many lines as the staged store has quads in its graph; else None."""
        found: dict[str, Path | None] = {}
        for name, path in self.paths.items():
            node = ox.NamedNode(name)
            present = staged.contains_named_graph(node)
            if self.lines[name] != (GraphStore._count_in(staged, name) if present else 0):
                return None
            found[name] = path if present else None
        return found


class _BlankMatch:
    """Which blank node of the old version of a program graph each one of the new version is.

    A blank node of a program graph is a list cell or a typed value, reached from the
    instance that owns it by one path of properties (``rdf:first``/``rdf:rest`` down a list,
    the attribute at the top): its *place*, named by a digest of the owner's IRI and that
    path. Two nodes of the two versions at the same place are taken for one node, and the new
    version's lines are written with the old label (:meth:`relabel`), so an unchanged list
    compares equal line for line. Nodes without one place of their own are left unmatched and
    are deleted and inserted like changed lines: a member of a SET of lists or typed values
    (several nodes at one place), a node reached twice, or one that nothing reaches. Any
    matching is correct -- what differs is still written -- a good one writes less.
    """

    def __init__(self, old: Path | None, new: Path | None) -> None:
        places = self.places(old)
        self.renamed: dict[bytes, bytes] = {}
        for place, label in self.places(new).items():
            if label is not None and (was := places.get(place)) is not None:
                self.renamed[label] = was
        self.kept = len(self.renamed)

    @staticmethod
    def places(path: Path | None) -> dict[bytes, bytes | None]:
        """place -> label for the blank nodes of an N-Triples file (None: several nodes there)."""
        place: dict[bytes, bytes | None] = {}  # label -> its place (None: it has none)
        parent: dict[bytes, tuple[bytes, bytes]] = {}  # label -> (the blank node above, property)
        props: dict[bytes, bytes] = {}  # one bytes object per property
        for line in _lines(path):
            if b"_:" not in line or (m := BLANK_OBJECT.search(line)) is None:
                continue
            label = m.group(1)
            subject, prop, _ = line.split(b" ", 2)
            if label in place or label in parent:  # reached twice: no place of its own
                place[label] = None
                parent.pop(label, None)
            elif subject[:2] == b"_:":
                parent[label] = (subject[2:], props.setdefault(prop, prop))
            else:
                place[label] = _digest(subject + b" " + prop)
        for label in parent:  # down from the nearest node whose place is known, iteratively
            down: list[bytes] = []
            seen: set[bytes] = set()
            node = label
            while node not in place and node in parent and node not in seen:
                down.append(node)
                seen.add(node)
                node = parent[node][0]
            above = place.get(node)  # None: a root without place, or a cycle
            for below in reversed(down):
                above = None if above is None else _digest(above + b" " + parent[below][1])
                place[below] = above
        found: dict[bytes, bytes | None] = {}
        for label, where in place.items():
            if where is not None:
                found[where] = None if where in found else label
        return found

    def relabel(self, line: bytes) -> bytes:
        """An N-Triples line of the new version with its blank nodes named as in the old one, or
        by a new random label when unmatched: the new version's own labels may be the load's
        (``_:b17``), unique in the load but not in the store."""
        if b"_:" not in line:
            return line
        if line[:2] == b"_:":
            end = line.index(b" ")
            line = b"_:" + self._label(line[2:end]) + line[end:]
        if (m := BLANK_OBJECT.search(line)) is not None:
            line = line[:m.start(1)] + self._label(m.group(1)) + b" .\n"
        return line

    def _label(self, label: bytes) -> bytes:
        was = self.renamed.get(label)
        if was is None:
            was = self.renamed[label] = uuid.uuid4().hex.encode("ascii")
        return was


def graph_layout(store: Store) -> GraphLayout:
    """What each named graph of ``store`` is, from its records (:class:`GraphLayout`): the program
    graphs (``p21:ExchangeStructure``) and the link graphs with their program (``p21:LinkGraph``,
    ``p21:linkedProgram``). One query, answered from the indexes of those two classes, on any store."""
    rows = store.query(f"SELECT ?g ?program WHERE {{ GRAPH ?g {{ {{ ?g a <{P21_NS}ExchangeStructure> }} UNION "
                       f"{{ ?g a <{P21_NS}LinkGraph> ; <{P21_NS}linkedProgram> ?program }} }} }}")
    programs: set[str] = set()
    links: dict[str, str] = {}
    for row in rows:
        graph, program = row[0], row[1]
        if not isinstance(graph, ox.NamedNode):
            continue
        if program is None:
            programs.add(graph.value)
        elif isinstance(program, ox.NamedNode):
            links[graph.value] = program.value
    return GraphLayout(frozenset(store.all_graphs()), frozenset(programs), links)


def program_graphs(store: Store) -> list[str]:
    """The graphs of loaded files (``p21:ExchangeStructure``), sorted: not the vocabulary, derived
    layers, link graphs or graphs a user added. The one answer to "which graphs are programs" for
    every command that counts, lists or picks programs (the query dataset, its warnings, the plan)."""
    return sorted(graph_layout(store).programs)


def directory_bytes(path: Path) -> int:
    """Bytes the files under ``path`` take on disk, a file hard-linked into several places (the
    store's generations share their SST files) counted once."""
    seen: dict[tuple[int, int], int] = {}
    for root, _dirs, files in os.walk(path):
        for name in files:
            try:
                st = os.stat(os.path.join(root, name))
            except FileNotFoundError:  # a generation collected meanwhile
                continue
            seen[(st.st_dev, st.st_ino)] = st.st_blocks * 512
    return sum(seen.values())


def _give_back_freed_memory() -> None:
    """Return the C heap's free memory to the system (glibc's ``malloc_trim``; elsewhere nothing).

    An in-memory Oxigraph store is many small C allocations; once it is dropped, glibc keeps
    the pages for later C allocations, which Python's own small objects never reuse (measured:
    a staged 100k-instance program kept 0.5 GB of the process after it was dropped).
    """
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _extend_in_calls(db: ox.Store, quads: Iterator[ox.Quad], batch: int | None = None) -> Iterator[int]:
    """Bulk-add ``quads`` in calls of at most ``batch`` (default :data:`REBUILD_BATCH`, read at
    each call; the bulk loader's memory grows with a call), the quads pulled one at a time;
    yields how many each call added."""
    batch = batch or REBUILD_BATCH
    while True:
        added = 0

        def counted(part: Iterator[ox.Quad]) -> Iterator[ox.Quad]:
            nonlocal added
            for quad in part:
                added += 1
                yield quad

        db.bulk_extend(counted(itertools.islice(quads, batch)))
        if added:
            yield added
        if added < batch:
            return


def _append(source: Path, out: BinaryIO) -> int:
    """Copy the file ``source`` to ``out``; how many lines it had."""
    lines = 0
    with open(source, "rb") as fh:
        while data := fh.read(1 << 20):
            out.write(data)
            lines += data.count(b"\n")
    return lines


def _lines(path: Path | None) -> Iterator[bytes]:
    """The lines of an N-Triples file, one at a time (none for None)."""
    if path is None:
        return
    with open(path, "rb") as fh:
        yield from fh


def _delete_rounds(work: list[tuple[ox.NamedNode, str, int]], budget: int,
                   threads: int) -> list[list[tuple[ox.NamedNode, str, int]]]:
    """Split the deletes ``work`` -- (graph, predicate, quads) -- into rounds of at most
    ``budget`` quads, the database flushed between rounds (see :data:`FLUSH_DELETES`). A round
    holds a predicate of a graph at most once (two deletes of the same quads at once would
    conflict) and a share of at most ``budget / threads`` of it (the threads stay busy), the
    largest first."""
    share = max(1, budget // threads)
    left = {(node, predicate): n for node, predicate, n in work if n > 0}
    rounds: list[list[tuple[ox.NamedNode, str, int]]] = []
    while left:
        part: list[tuple[ox.NamedNode, str, int]] = []
        room = budget
        for (node, predicate), n in sorted(left.items(), key=lambda kv: -kv[1]):
            take = min(n, share, room)
            if take <= 0:
                break
            part.append((node, predicate, take))
            room -= take
            if n == take:
                del left[(node, predicate)]
            else:
                left[(node, predicate)] = n - take
        rounds.append(part)
    return rounds


def _line_pieces(text: str, size: int) -> Iterator[str]:
    """``text`` (lines) in pieces of about ``size`` characters, each ending at the end of a line."""
    start = 0
    while start < len(text):
        end = text.find("\n", start + size)
        end = len(text) if end < 0 else end + 1
        yield text[start:end]
        start = end


def _compared_parts(old: Path | None, new: Path | None, relabel: Callable[[bytes], bytes],
                    scratch: Path) -> Iterator[tuple[Path | None, Iterator[bytes]]]:
    """The old and the new N-Triples file of one graph as pairs of (old lines, new lines
    relabelled) to compare with each other, each pair small enough to hold the old lines in a
    set: the files whole when the old one has at most :data:`COMPARE_BYTES`, else parts of
    both split by a hash of each (relabelled) line, written under ``scratch`` and removed
    once compared. Equal lines fall into the same part."""
    size = old.stat().st_size if old is not None else 0
    parts = -(-size // COMPARE_BYTES)
    relabelled = (relabel(line) if b"_:" in line else line for line in _lines(new))  # the test saves a call a line
    if parts <= 1:
        yield old, relabelled
        return
    scratch.mkdir()
    olds = _split_lines(_lines(old), parts, scratch / "old")
    news = _split_lines(relabelled, parts, scratch / "new")
    for old_part, new_part in zip(olds, news, strict=True):
        yield old_part, _lines(new_part)
        old_part.unlink()
        new_part.unlink()


def _split_lines(lines: Iterable[bytes], parts: int, stem: Path) -> list[Path]:
    """Write ``lines`` to ``parts`` files named after ``stem``, each line to the file its hash
    chooses (a hash of this process: both versions are split in it)."""
    paths = [stem.with_name(f"{stem.name}{k}.nt") for k in range(parts)]
    files = [open(path, "wb", buffering=1 << 20) for path in paths]
    try:
        for line in lines:
            files[hash(line) % parts].write(line)
    finally:
        for fh in files:
            fh.close()
    return paths


def _line_set(path: Path | None) -> set[bytes]:
    """The lines of an N-Triples file as a set (built in C: a quarter of the time that digesting
    them line by line in Python took; the lines of 1.3M quads take about 180 MB)."""
    if path is None:
        return set()
    with open(path, "rb") as fh:
        return set(fh)


def _has_blank(line: bytes) -> bool:
    """Whether an N-Triples line (as Oxigraph writes it) has a blank node as subject or object."""
    return b"_:" in line and (line.startswith(b"_:") or BLANK_OBJECT.search(line) is not None)


def _digest(line: bytes) -> bytes:
    return hashlib.blake2b(line, digest_size=16).digest()


def _command_line() -> str:
    import sys

    name = Path(sys.argv[0]).name if sys.argv and sys.argv[0] else "python"
    return " ".join([name, *sys.argv[1:]])[:200]
