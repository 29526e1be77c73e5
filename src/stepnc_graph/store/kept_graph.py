"""A graph of the store on disk written out as N-Triples from the text its last load kept
(:mod:`stepnc_graph.store.kept`), instead of dumped from Oxigraph.

Dumping a graph costs Oxigraph 5-11 µs of CPU a quad, as it decodes every term (a generated
100k-instance program's 1.17M quads: 12-14 CPU-s, measured); its kept text costs a decompression
(0.7 CPU-s there) and, where the store's own labels of blank nodes are needed, one query per
predicate of the lines with a blank node. Used by a replacement (the old version) and by exports.
"""

from __future__ import annotations

import zlib
from pathlib import Path

import pyoxigraph as ox

from stepnc_graph.store.batches import count_in
from stepnc_graph.store.difference import append_file
from stepnc_graph.store.kept import blocks, read_without_blank_nodes


def graph_from_kept(db: ox.Store, graph: str, kept: Path, lines: int, path: Path, store_labels: bool) -> bool:
    """Write graph ``graph`` of ``db`` to ``path`` as N-Triples from the kept text ``kept`` (of
    ``lines`` lines). False, and nothing to use in ``path``, when the file is damaged or cut short
    or the line counts differ from the database's.

    ``store_labels=False``: the kept text as it is. Its blank nodes have the labels the load wrote,
    not those Oxigraph's bulk loader gave them, so the text describes the graph on its own (an
    export of that graph alone) but cannot be joined with another graph's text.

    ``store_labels=True``: the lines without blank node as kept, the others read from the database,
    predicate by predicate, so every blank node has the database's label (6 s for a 1M-instance
    program's 1.66M such lines, where the dumps of its two graphs take about 120 s of CPU)."""
    node = ox.NamedNode(graph)
    blank = path.with_name(path.stem + "-blank.nt")
    try:
        with open(path, "wb", buffering=1 << 20) as out:
            if not store_labels:
                written = 0
                for block in blocks(kept):
                    out.write(block)
                    written += block.count(b"\n")
                return written == lines == count_in(db, graph)
            found = read_without_blank_nodes(kept, out)
            if found.lines + found.blank != lines:
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
                read += append_file(blank, out)
    except (OSError, EOFError, zlib.error, UnicodeDecodeError, SyntaxError):
        return False
    finally:
        blank.unlink(missing_ok=True)
    return read == found.blank and found.lines + read == count_in(db, graph)
