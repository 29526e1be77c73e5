"""A replacement by difference: the new version of a program's graphs staged beside the store,
compared with the old version as N-Triples lines, and only what changed deleted and inserted.

Deleting costs Oxigraph more than loading does (see docs/loading.md), so a replacement that
deleted the old version and loaded the new one cost two to three loads beside other programs;
this one costs 0.7-1.5. :class:`Replacement` runs one, inside the store's write
(:meth:`stepnc_graph.store.transaction.Transaction.write`); its pieces (the tee, the blank-node match, the
deleter thread, the part-by-part comparison) are in :mod:`.difference`.
"""

from __future__ import annotations

import itertools
import shutil
import threading
import traceback
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.core.naming import VOCABULARY_GRAPH
from stepnc_graph.store import tuning
from stepnc_graph.store.batches import count_in, extend_in_calls
from stepnc_graph.store.contract import Chunk
from stepnc_graph.store.difference import (
    BlankMatch,
    Deleter,
    Tee,
    compared_parts,
    file_lines,
    give_back_freed_memory,
    has_blank,
    line_set,
)
from stepnc_graph.store.errors import StoreError
from stepnc_graph.store.removal import Removal
from stepnc_graph.store.kept import KeptText
from stepnc_graph.store.kept_graph import graph_from_kept

if TYPE_CHECKING:
    from stepnc_graph.store.embedded import GraphStore


class Replacement:
    """One replacement by difference of a graph and its companions in ``store`` (see the module
    docstring); :meth:`replace` runs it."""

    def __init__(self, store: GraphStore) -> None:
        self.store = store

    def replace(self, graph: str, chunks: Iterable[Chunk],
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
        :data:`~stepnc_graph.store.tuning.STAGE_IN_MEMORY_QUADS`), then each graph is compared with the one on disk as
        N-Triples lines (the old version from the text its load kept, ``kept``, see
        :func:`~stepnc_graph.store.kept_graph.graph_from_kept`; else dumped), and only the lines that changed are deleted and
        inserted. Blank nodes
        (list cells, typed values), which no two loads name alike, are first matched between the
        versions by their place under the instance that owns them (:class:`BlankMatch`), so an
        unchanged list compares equal and keeps its nodes. A re-load of the same file then
        changes only its load's provenance. If the counts do not come out as the staged ones,
        the graphs are dropped and loaded whole from the staged version: never a wrong graph.
        The texts go through files in ``DIR/difference/`` (removed after, or by the next
        writer's recovery). :attr:`last_difference` counts what was written.

        The loader rewrites the vocabulary graph only when it is stale; the staged store gets
        the vocabulary's own description from disk, so it is compared only when rewritten.
        """
        scratch = self.store._file("difference")
        shutil.rmtree(scratch, ignore_errors=True)
        scratch.mkdir()
        try:
            new, old, dumped = self._stage(graph, chunks, before_commit, [graph, *companions], scratch, in_memory,
                                           kept)
            give_back_freed_memory()  # the staged store was the peak of an in-memory replacement
            shutil.rmtree(scratch / "staged", ignore_errors=True)
            self.store.last_removal = "difference"
            match = BlankMatch(old[graph], new[graph])
            staged_counts = self._apply_difference(old, new, match, scratch)
            self.store.last_difference["staged in memory"] = int(in_memory)
            self.store.last_difference["new version dumped"] = int(dumped)
            deleted = self.store.last_difference["deleted"]

            def adds_up() -> bool:
                return all(staged_counts[n] == self.store.count(n) for n in new)

            if not adds_up():
                self.store.last_removal = "difference, then delete"
                present = [n for n in new if self.store.has_graph(n)]
                deleted += Removal(self.store).quads_in(present)
                Removal(self.store).delete_in_batches(present)
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
        is written out (from the text its load kept, :func:`~stepnc_graph.store.kept_graph.graph_from_kept`, or dumped). Returns the N-Triples files of the new and of the old version, graph by
        graph (None: no such graph; the vocabulary graph is among them when the load rewrote it),
        and whether the new version was dumped (see below). The staged store is dropped on return.

        The new version's files are the text the load wrote (:class:`Tee`: its chunks, its
        :class:`~stepnc_graph.store.contract.Joint` lines, what ``before_commit`` added as N-Triples), when each holds as
        many lines as the staged store holds quads in that graph -- so no line was lost,
        repeated or merged with another. Else they are dumps of the staged store, which cost
        about as much as the dumps of the old version (Oxigraph decodes every term: 5-8 µs a
        quad, measured on a 1M-instance program's 13.6M quads).
        """
        staged = ox.Store() if in_memory else ox.Store(str(scratch / "staged"))
        vocabulary = ox.NamedNode(VOCABULARY_GRAPH)
        staged.extend(self.store._db.quads_for_pattern(vocabulary, None, None, vocabulary))
        seeded = len(staged)
        old: dict[str, Path | None] = {}
        errors: list[BaseException] = []
        from_kept: list[str] = []

        def old_version(k: int) -> Path | None:
            name, path = names[k], scratch / f"old{k}.nt"
            try:
                if not self.store._disk.contains_named_graph(ox.NamedNode(name)):
                    return None
                if name in kept and graph_from_kept(self.store._disk, name, self.store._kept.path(kept[name]), kept[name].lines,
                                                     path, store_labels=True):
                    from_kept.append(name)
                    return path
                return self._dump_graph(self.store._disk, name, path)
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
        self.store._parked, self.store._store = self.store._store, staged
        self.store._tee = tee = Tee(names, scratch, self.store._kept.writing(names))
        dumping = threading.Thread(target=dump_old, daemon=True)
        dumping.start()
        try:
            try:
                self.store._bulk_load(graph, chunks, in_memory=in_memory)
                if before_commit is not None:
                    before_commit(lambda name: name)
            finally:
                self.store._tee = None
                tee.close()
                dumping.join()
                self.store._store, self.store._parked = self.store._parked, None
            if errors:
                raise errors[0]
            teed = tee.new_version(staged)
        except BaseException:
            tee.discard()
            raise
        self.store.last_difference = {"old version kept": len(from_kept)}
        if teed is None:
            tee.discard()
            for path in tee.paths.values():
                path.unlink(missing_ok=True)
        else:
            self.store._tx.kept_written.update(tee.keep())
        to_dump = names if teed is None else []  # and the vocabulary, if the load rewrote it
        if staged.contains_named_graph(vocabulary) and count_in(staged, VOCABULARY_GRAPH) != seeded:
            to_dump = [*to_dump, VOCABULARY_GRAPH]
            old[VOCABULARY_GRAPH] = self._dump_graph(self.store._db, VOCABULARY_GRAPH, scratch / "old-vocabulary.nt")
        give_back_freed_memory()  # what completing the graph took, before its dump
        new = dict(teed or {})
        with ThreadPoolExecutor(tuning.LOAD_THREADS) as pool:  # the dumps release the GIL: the graphs side by side
            paths = pool.map(lambda k: self._dump_graph(staged, to_dump[k], scratch / f"staged{k}.nt"),
                             range(len(to_dump)))
            new.update(zip(to_dump, paths, strict=True))
        return new, old, teed is None

    @staticmethod
    def _relabelled(new: dict[str, Path | None], match: BlankMatch, path: Path) -> Path:
        """The files ``new`` as one N-Quads file ``path``, blank nodes named by ``match`` (the
        load's own labels are not unique in the store, see :meth:`BlankMatch.relabel`)."""
        with open(path, "wb", buffering=1 << 20) as out:
            for name, lines in new.items():
                suffix = b" <" + name.encode("utf-8") + b"> .\n"
                for line in file_lines(lines):
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

    def _apply_difference(self, old: dict[str, Path | None], new: dict[str, Path | None], match: BlankMatch,
                          scratch: Path) -> dict[str, int]:
        """Make each graph on disk, dumped to the N-Triples file ``old`` gives for it, hold the
        file ``new`` gives for it (None: no such graph), blank nodes of the new version named
        as ``match`` gives (see :meth:`replace`). One graph at a time, one part
        of it at a time (:func:`compared_parts`): its old lines in a set, the new ones read one
        at a time; the lines to delete go to a file per part, deleted by a :class:`Deleter`
        while the next part is compared; the lines to insert to one file, inserted once all
        is deleted. Returns how many lines each new file has (the quads each graph must end
        with)."""
        deleted = inserted = blank = 0
        lines: dict[str, int] = {}
        inserts = scratch / "insert.nq"
        deleter = Deleter(self)
        try:
            with open(inserts, "wb") as out:
                for k, (name, path) in enumerate(new.items()):
                    node = ox.NamedNode(name)
                    suffix = b" <" + name.encode("utf-8") + b"> .\n"
                    count = 0
                    parts = compared_parts(old.get(name), path, match.relabel, scratch / f"part{k}")
                    for n, (old_part, new_lines) in enumerate(parts):
                        unmatched = line_set(old_part)  # old lines no new line has matched yet
                        for line in new_lines:
                            count += 1
                            if line in unmatched:
                                unmatched.remove(line)  # a graph's lines are distinct, so are relabelled ones
                            else:
                                out.write(line[:-3] + suffix)  # each line ends " .\n"
                                inserted += 1
                                blank += has_blank(line)
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
        self.store._tx.deletes_logged = True
        self.store.last_difference.update({"deleted": deleted, "inserted": inserted, "inserted with a blank node": blank,
                                     "blank nodes kept": match.kept})
        return lines

    def _delete_lines(self, node: ox.NamedNode, path: Path, unflushed: int = 0) -> int:
        """Delete the N-Triples lines of the file ``path`` (as Oxigraph dumped them) from graph
        ``node``, :data:`~stepnc_graph.store.tuning.DELETE_LINES` at a time: ground ones by ``DELETE DATA``, the ones with a
        blank node (which SPARQL cannot name) parsed with their labels kept and removed one by
        one. The memory tables are flushed after every :data:`~stepnc_graph.store.tuning.FLUSH_DELETES` lines, as batched
        deletes do between rounds (their tombstones stay in memory until then), counting the
        ``unflushed`` lines deleted before; returns the count left. The caller sees to it that
        no other thread deletes meanwhile."""
        with open(path, "rb") as fh:
            while batch := list(itertools.islice(fh, tuning.DELETE_LINES)):
                if unflushed >= tuning.FLUSH_DELETES:
                    Removal(self.store).flush()
                    unflushed = 0
                unflushed += len(batch)
                ground: list[bytes] = []
                blank: list[bytes] = []
                for line in batch:
                    (blank if has_blank(line) else ground).append(line)
                if ground:
                    self.store._db.update(f"DELETE DATA {{ GRAPH {node} {{ {b''.join(ground).decode('utf-8')} }} }}")
                for triple in ox.parse(b"".join(blank), format=ox.RdfFormat.N_TRIPLES):
                    self.store._db.remove(ox.Quad(triple.subject, triple.predicate, triple.object, node))
        return unflushed

    def _insert(self, path: Path, graph: str | None = None) -> None:
        """Add the N-Quads file ``path`` (N-Triples into ``graph`` when one is given), its blank
        node labels kept (they are the staged store's random 128-bit ids, so a blank node that two
        graphs share -- the derived layer points at the program's list cells -- stays one node
        across calls and files), in bulk calls of :data:`~stepnc_graph.store.tuning.INSERT_BATCH` quads."""
        if graph is None:
            quads = iter(ox.parse(path=str(path), format=ox.RdfFormat.N_QUADS))
        else:
            node = ox.NamedNode(graph)
            quads = (ox.Quad(t.subject, t.predicate, t.object, node)
                     for t in ox.parse(path=str(path), format=ox.RdfFormat.N_TRIPLES))
        for _ in extend_in_calls(self.store._db, quads, tuning.INSERT_BATCH):
            pass
