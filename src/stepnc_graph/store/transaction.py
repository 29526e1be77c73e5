"""The write transaction of the store on disk: the one way a write is made, and the state it runs with.

A write marks ``work/`` dirty, changes it (Oxigraph's bulk loader is fast but not transactional),
then publishes it as the next generation (:func:`~stepnc_graph.store.directory.publish`); any
exception rolls ``work/`` back to the published generation and is raised again. What the running
write has done that its commit or rollback must finish -- the kept texts it wrote, the graphs it
touched, the deleted quads it counts, the batched deletes in the write-ahead log -- is held here,
not in the store.
"""

from __future__ import annotations

import gc
import os
import sys
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.store import directory, tuning
from stepnc_graph.store.errors import StoreWriteError
from stepnc_graph.store.files import DELETED_QUADS, fsync_dir
from stepnc_graph.store.kept import KeptText

if TYPE_CHECKING:
    from stepnc_graph.store.embedded import GraphStore


class Transaction:
    """The writes of ``store`` (on disk), one at a time, and the running one's state."""

    def __init__(self, store: GraphStore) -> None:
        self.store = store
        #: the generation the running write started from (None: no write runs), the texts it kept
        #: and the graphs it touched (None: perhaps any), for the kept texts' index (see
        #: stepnc_graph.store.kept)
        self.since: str | None = None
        self.kept_written: dict[str, KeptText] = {}
        self.touched: set[str] | None = set()
        #: deleted_quads once this write commits (see settle)
        self.deleted_after: int | None = None
        #: work/'s write-ahead log holds batched deletes (see drop_write_ahead_log)
        self.deletes_logged = False

    @property
    def path(self) -> Path:
        assert self.store.path is not None
        return self.store.path

    @contextmanager
    def write(self, touches: list[str] | None) -> Iterator[dict[str, KeptText]]:
        """One write to the store on disk, the only way one is made: ``work/`` marked dirty, the
        graphs it ``touches`` noted (None: it rewrites the database, no kept text is read), then
        committed as the next generation, or rolled back on any exception, which is raised again
        (:meth:`failed`). Yields the kept texts that describe the database now."""
        self.begin()
        try:
            kept: dict[str, KeptText] = {}
            if touches is not None:  # an unload or a replacement (not a compaction)
                self.store.compacted = False
                kept = self.usable_kept()
                self.touch(touches)
            yield kept
            self.commit()
        except BaseException as exc:
            self.failed(exc)
            raise

    def begin(self) -> None:
        """Mark ``work/`` as possibly different from the published generation."""
        if self.store.path is None:
            return
        self.store.prepare_to_write()
        dirty = self.path / "work.dirty"
        try:
            if not dirty.exists():
                dirty.write_text("")
                fsync_dir(self.path)
        except OSError as e:
            raise self.disk_error(e) or e from None
        self.since = directory.current(self.path)

    def commit(self) -> None:
        """Publish ``work/`` as the next generation, with its deleted-quads count and kept texts."""
        if self.store.path is None:
            return
        if self.deletes_logged:  # before the checkpoint, which would copy the log
            self.drop_write_ahead_log()
        self.store._publish()
        self._count_deleted()
        written, touched, since = self.kept_written, self.touched, self.since
        self.kept_written, self.touched, self.since = {}, set(), None
        assert self.store.generation is not None
        self.store._kept.publish(self.store.generation, since, written, touched)
        directory.collect(self.path)

    def disk_error(self, exc: BaseException) -> StoreWriteError | None:
        """A write's error as a :class:`StoreWriteError` naming the store, when the store's own
        files refused it (a full disk, a read-only one: Oxigraph's errors name no file, Python's a
        file in the store); None for any other error, such as an input file that cannot be read."""
        if not isinstance(exc, OSError) or isinstance(exc, StoreWriteError) or self.store.path is None:
            return None
        name = exc.filename
        if name is not None and not Path(os.path.abspath(name)).is_relative_to(Path(os.path.abspath(self.path))):
            return None
        reason = f"{exc.strerror} ({name})" if exc.strerror and name else exc.strerror or str(exc)
        error = StoreWriteError(f"cannot write to the store in {self.path}: {reason}; the store is as it was before")
        error.errno = exc.errno
        return error

    def failed(self, exc: BaseException) -> None:
        """Roll a failed write back and raise its error (see :meth:`disk_error`)."""
        self.rollback()
        if (error := self.disk_error(exc)) is not None:
            raise error from exc

    def rollback(self) -> None:
        """Back to the published generation (the writer's lock is still held).

        ``work/`` stays marked dirty until it is rebuilt, so if the database cannot
        be reopened here (a caller still holds ``store.oxigraph``), the next
        writer's open recovers it.
        """
        store = self.store
        if store.path is None:
            return
        self.deletes_logged = False  # work/ is rebuilt from the published generation
        self.deleted_after = None
        for kept in self.kept_written.values():
            store._kept.path(kept).unlink(missing_ok=True)
        self.kept_written, self.touched, self.since = {}, set(), None
        old, store._store = store._store, None
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
            store._closed_because = (f"the store in {store.path} was rolled back, but this process still holds "
                                     f"its database (the failed operation's traceback); open it again")
            return
        try:
            directory.recover(self.path)
            store._store = ox.Store(str(self.path / "work"))
        except OSError as e:
            store._closed_because = (f"the store in {store.path} was rolled back on disk, but this process "
                                     f"could not reopen it ({e}); open it again")

    def usable_kept(self) -> dict[str, KeptText]:
        """The kept texts that describe the database now: those of the generation it was
        published as, but for graphs changed since by writes outside a load."""
        if self.touched is None:
            return {}
        return {g: k for g, k in self.store._kept.valid(self.since).items() if g not in self.touched}

    def readable_kept(self) -> dict[str, KeptText]:
        """The kept texts that describe the database a reader reads now: those of the generation
        the store read or last published, while no write runs (its work is not published) and no
        writer handed out the database (``touched`` None: it may have been written through)."""
        if self.store.path is None or self.since is not None or self.touched is None:
            return {}
        return self.store._kept.valid(self.store.generation)

    def touch(self, graphs: Sequence[str] | None) -> None:
        """Note that the current write changes ``graphs`` (None: perhaps any), whose kept texts
        then describe them no more (see :mod:`stepnc_graph.store.kept`)."""
        if graphs is None:
            self.touched = None
        elif self.touched is not None:
            self.touched.update(graphs)

    def touch_any_outside_a_write(self) -> None:
        """A write outside a load (``update``, ``add_quads``) may have changed any graph."""
        if self.since is None:
            self.touch(None)

    # -- deleted quads and compaction -------------------------------------------------------

    def settle(self, deleted: int, held: int, compact: bool = False) -> None:
        """Count ``deleted`` quads against the database, which holds about ``held`` quads, and
        compact it (``optimize``: the space of deleted quads comes back) when the quads deleted
        since its last compaction reach :data:`~stepnc_graph.store.tuning.COMPACT_AT` of ``held``, or when ``compact``
        asks for it. Not at every unload: a compaction rewrites the whole database, so its cost
        grows with the store, not with what was deleted (see :data:`~stepnc_graph.store.tuning.COMPACT_AT`)."""
        pending = self.store.deleted_quads + deleted
        self.store.compacted = compact or pending >= tuning.COMPACT_AT * max(held, 1)
        if self.store.compacted:
            self.store._db.optimize()
            pending = 0
        self.deleted_after = pending

    def _count_deleted(self) -> None:
        """Write the count of deleted quads this write leaves (see :meth:`settle`), after the
        generation it belongs to is published. A writer killed in between leaves the count of the
        write before: the only effect is a later compaction."""
        after, self.deleted_after = self.deleted_after, None
        if after is None:
            return
        tmp = self.path / (DELETED_QUADS + ".tmp")
        tmp.write_text(f"{after}\n")
        os.replace(tmp, self.path / DELETED_QUADS)

    def drop_write_ahead_log(self) -> None:
        """Reopen ``work/`` so that RocksDB deletes the write-ahead log of batched deletes.

        The log holds every tombstone written, and RocksDB keeps it after the memtables are
        flushed until the database is opened again; a checkpoint would copy it into the published
        generation (the figures are in docs/loading.md, "The store's tuning, measured"). Skipped
        when someone else still holds the database (``store.oxigraph``): the next open drops it.
        """
        self.deletes_logged = False
        if sys.getrefcount(self.store._store) > 2:  # the attribute and the call's argument
            return
        self.store._close_db()
        self.store._store = ox.Store(str(self.path / "work"))
