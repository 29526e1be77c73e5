"""Removing graphs from the store on disk, and the cost model that chooses how.

Oxigraph deletes quad by quad in transactions: about 11 µs of CPU a quad beside a large store,
where copying the rest of the store into a fresh database costs about 10 (the figures are in
:mod:`.tuning` and docs/loading.md). So a graph is removed by deleting its quads in bounded
batches, or -- when it is a large part of the store -- by rebuilding the database from the
other graphs, whichever costs less; a compaction is such a rebuild of every graph.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.store import tuning
from stepnc_graph.store.batches import count_in, delete_rounds, extend_in_calls
from stepnc_graph.store.kept import KeptText

if TYPE_CHECKING:
    from stepnc_graph.store.embedded import GraphStore


class Removal:
    """The removals of one write to ``store`` (see the module docstring)."""

    def __init__(self, store: GraphStore) -> None:
        self.store = store

    def _quads_about(self, graphs: Sequence[str] | None, kept: dict[str, KeptText]) -> int:
        """About the quads of ``graphs`` (None: of the database), for choosing how to remove and
        when to compact: a graph's kept text gives its count (unless the text repeated a line),
        the others are counted (Oxigraph counts by scanning: 5.9 s for 40.8M quads, 2 s for a
        program graph of 8M)."""
        if graphs is not None:
            return sum(kept[g].lines if g in kept else self.store.count(g) for g in graphs)
        counted = count_in(self.store._db, None) + sum(self.store.count(g) for g in self.store.all_graphs() if g not in kept)
        return counted + sum(k.lines for g, k in kept.items() if self.store.has_graph(g))

    def quads_in(self, graphs: Sequence[str]) -> int:
        return sum(self.store.count(g) for g in graphs if self.store.has_graph(g))

    def choose(self, graphs: Sequence[str],
                 kept: dict[str, KeptText]) -> tuple[str | None, list[str], int, int]:
        """How removing ``graphs`` costs less (see the module docstring): "rebuild", "delete",
        or None when none of them is there; with the ones present, their quads and the
        database's (about: see :meth:`_quads_about`)."""
        present = [g for g in graphs if self.store.has_graph(g)]
        if not present:
            return None, [], 0, 0
        removed, held = self._quads_about(present, kept), self._quads_about(None, kept)
        how = "rebuild" if (held - removed) * tuning.REBUILD_COST < removed * tuning.DELETE_COST else "delete"
        return how, present, removed, held

    def remove(self, how: str | None, present: list[str]) -> None:
        """Remove the graphs ``present`` the way :meth:`choose` chose."""
        if how is None:
            return
        self.store.last_removal = how
        if how == "rebuild":
            self.rebuild_without(set(present))
        else:
            self.delete_in_batches(present)

    def delete_in_batches(self, graphs: Sequence[str]) -> None:
        """Delete the quads of ``graphs`` (a program graph and its companions) in transactions of
        bounded size (flat memory), predicate by predicate, :data:`~stepnc_graph.store.tuning.DELETE_BATCH` quads a
        transaction, on :data:`~stepnc_graph.store.tuning.LOAD_THREADS` threads, the largest predicates first (balanced
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
            counts = self.store._db.query(f"SELECT ?p (COUNT(*) AS ?n) WHERE {{ GRAPH {node} {{ ?s ?p ?o }} }} GROUP BY ?p")
            work += [(node, str(row[0]), int(row[1].value)) for row in counts]  # type: ignore[union-attr]
            del counts  # a query's rows hold the database open
        with ThreadPoolExecutor(tuning.LOAD_THREADS) as pool:
            for k, part in enumerate(delete_rounds(work, tuning.FLUSH_DELETES, tuning.LOAD_THREADS)):
                if k:
                    self.flush()
                list(pool.map(self._delete_predicate, part))
        self.store._tx.deletes_logged = True
        for node in nodes:
            self.store._db.remove_graph(node)  # the name, and any quad added since the count

    def flush(self) -> None:
        """Write the database's memory tables to disk, between two rounds of batched deletes.

        Never while a delete runs on another thread: RocksDB's manual flush then sometimes
        waits forever for a flush that is never scheduled (seen here in 4 of 20 runs of the
        batched-delete test, flushing from the deleting threads: background threads idle, the
        flushing one in ``DBImpl::WaitForFlushMemTables``)."""
        self.store._db.flush()

    def _delete_predicate(self, item: tuple[ox.NamedNode, str, int]) -> None:
        """Delete ``n`` quads of one predicate in one graph, :data:`~stepnc_graph.store.tuning.DELETE_BATCH` a transaction."""
        node, predicate, n = item
        for done in range(0, n, tuning.DELETE_BATCH):
            self.store._db.update(f"DELETE {{ GRAPH {node} {{ ?s {predicate} ?o }} }} WHERE {{ {{ SELECT ?s ?o WHERE "
                            f"{{ GRAPH {node} {{ ?s {predicate} ?o }} }} LIMIT {min(tuning.DELETE_BATCH, n - done)} }} }}")

    def rebuild_without(self, dropped: set[str], progress: Callable[[int, int], None] | None = None) -> None:
        """Replace ``work/`` by a fresh database holding every graph but ``dropped``.

        ``progress(done, total)`` is told the quads copied after each bulk call. On a failure
        (or an exception from ``progress``) no reference to either database stays in this
        frame, so the rollback can reopen ``work/``.
        """
        rebuild = self.store._file("rebuild")
        shutil.rmtree(rebuild, ignore_errors=True)
        fresh = ox.Store(str(rebuild))
        keep = [g for g in self.store._db.named_graphs() if not (isinstance(g, ox.NamedNode) and g.value in dropped)]
        total = len(self.store._db) - self.quads_in(sorted(dropped)) if progress else 0
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
        self.store._close_db()
        shutil.rmtree(self.store._file("work"))
        rebuild.rename(self.store._file("work"))
        self.store._store = ox.Store(str(self.store._file("work")))
        self.store._tx.deleted_after = 0  # a fresh database: nothing deleted in it

    def _copy_graph(self, fresh: ox.Store, graph: ox.NamedNode | ox.BlankNode | ox.DefaultGraph) -> Iterator[int]:
        """Copy ``graph`` into ``fresh``, yielding how many quads each bulk call copied. A
        generator, so that the iterator over the database lives in its frame only, not in the
        caller's."""
        yield from extend_in_calls(fresh, iter(self.store._db.quads_for_pattern(None, None, None, graph)))
        if isinstance(graph, (ox.NamedNode, ox.BlankNode)):
            fresh.add_graph(graph)  # an empty named graph stays a graph
