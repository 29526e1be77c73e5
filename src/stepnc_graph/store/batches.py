"""Feeding Oxigraph in bounded pieces: text as a stream, text cut at line ends, quads in bulk
calls, delete rounds balanced over threads (the sizes are in :mod:`.tuning`)."""

from __future__ import annotations

import io
import itertools
from collections.abc import Iterable, Iterator
from typing import Any

import pyoxigraph as ox

from stepnc_graph.store import tuning


class ChunkStream(io.RawIOBase):
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


def line_pieces(text: str, size: int) -> Iterator[str]:
    """``text`` (lines) in pieces of about ``size`` characters, each ending at the end of a line."""
    start = 0
    while start < len(text):
        end = text.find("\n", start + size)
        end = len(text) if end < 0 else end + 1
        yield text[start:end]
        start = end


def extend_in_calls(db: ox.Store, quads: Iterator[ox.Quad], batch: int | None = None) -> Iterator[int]:
    """Bulk-add ``quads`` in calls of at most ``batch`` (default :data:`~stepnc_graph.store.tuning.REBUILD_BATCH`, read at
    each call; the bulk loader's memory grows with a call), the quads pulled one at a time;
    yields how many each call added."""
    batch = batch or tuning.REBUILD_BATCH
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


def delete_rounds(work: list[tuple[ox.NamedNode, str, int]], budget: int,
                   threads: int) -> list[list[tuple[ox.NamedNode, str, int]]]:
    """Split the deletes ``work`` -- (graph, predicate, quads) -- into rounds of at most
    ``budget`` quads, the database flushed between rounds (see :data:`~stepnc_graph.store.tuning.FLUSH_DELETES`). A round
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


def count_in(store: ox.Store, graph: str | None) -> int:
    """Quads in ``graph`` of ``store`` (None: its default graph), counted by Oxigraph."""
    pattern = "?s ?p ?o" if graph is None else f"GRAPH {ox.NamedNode(graph)} {{ ?s ?p ?o }}"
    rows = store.query(f"SELECT (COUNT(*) AS ?n) WHERE {{ {pattern} }}")
    assert isinstance(rows, ox.QuerySolutions)
    [row] = list(rows)
    return int(row[0].value)
