"""The throw-away store ``validate FILE`` loads files into: in memory, or on disk when they are
large; what goes into it beside the program graphs (the shapes graph, when a check reads
``$shapesGraph``) and what may be left out of them (the position triples, when no check reads
them)."""

from __future__ import annotations

import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.naming import DATA_BASE
from stepnc_graph.validation.compiled import CompiledShapes
from stepnc_graph.validation.engine import SHAPES_GRAPH
from stepnc_graph.validation.shapes import ShapesError


def rdf_graph(path: Path, taken: set[str]) -> str:
    """The graph an RDF data file is validated in: named by its file, as a program's is."""
    from urllib.parse import quote

    graph = DATA_BASE + quote(path.name, safe="")
    n = 2
    while graph in taken:
        graph = f"{DATA_BASE}{quote(path.name, safe='')}-{n}"
        n += 1
    taken.add(graph)
    return graph


def add_shapes_graph(store: ox.Store, shapes: CompiledShapes) -> None:
    """The shapes files as the named graph ``$shapesGraph`` stands for (SHACL 5.3.1)."""
    from stepnc_graph.validation.shapes import base_iri

    target = ox.NamedNode(SHAPES_GRAPH)
    for f in shapes.files:
        try:
            store.extend([ox.Quad(t.subject, t.predicate, t.object, target)
                          for t in ox.parse(path=str(f), format=ox.RdfFormat.TURTLE, base_iri=base_iri(str(f)))])
        except (SyntaxError, OSError) as exc:
            raise ShapesError(f"{f}: {exc}") from None


#: Input above this size is validated in a temporary on-disk store instead of memory: Oxigraph's
#: in-memory store holds about 70 bytes of RAM per byte of Part 21 (measured: 1M instances, 63 MB,
#: peaked at 4.4 GB), its on-disk store keeps a bounded cache. Below it, memory is faster (100k
#: instances, 6 MB: 3.6 s against 5.7 s to load).
MEMORY_VALIDATION_BYTES = 16_000_000


#: Input below this size is loaded whole when what the checks read is not known yet (shapes of
#: one's own): working it out (:func:`.reads.properties_read`) takes some 40-60 ms of pattern
#: matching, more than leaving the attributes out saves on a small program (in-process, medians of
#: 5: the 89-instance example 141 ms against 79 loaded whole; a replicated real program of 1k
#: instances, 61 KB, 192 against 161; of 10k, 605 KB, 1,080 against 1,060). For the shipped checks
#: the build worked it out, and leaving out is the cheaper way at every size (medians of 7, CPU:
#: the example 36 ms against 35 loaded whole, 1k 101 against 116, 10k 757 against 847). Read as
#: ``throwaway.HOLD_BYTES`` when validating, so a test may set it.
HOLD_BYTES = 1_000_000


def properties_kept(store: Any, shapes: CompiledShapes, size: int) -> frozenset[str] | None:
    """The properties the throw-away graph of input of ``size`` bytes keeps (None: every one): in
    memory, those the checks read, unless what they read is not known yet and the input is small
    (:data:`HOLD_BYTES`); on disk every one (the lines of the others are not held back there)."""
    held = store.path is None and (shapes.reads_known or size >= HOLD_BYTES)
    return shapes.properties_read() if held else None


def input_bytes(paths: Sequence[str | Path]) -> int:
    """The size of the files to validate, as the load will find them (standard input counts 0)."""
    from stepnc_graph.loading.sources import STDIN_GRAPH, plan_sources

    return sum(s.path.stat().st_size for s in plan_sources(list(paths), stdin_graph=STDIN_GRAPH)
               if s.path is not None)


@contextmanager
def throwaway_store(paths: Sequence[str | Path], size: int | None = None) -> Iterator[Any]:
    """An in-memory store for the files ``paths``, or a temporary on-disk one when they are large
    (``size``: their :func:`input_bytes`, if the caller has it)."""
    from stepnc_graph.store import open_store

    if (input_bytes(paths) if size is None else size) <= MEMORY_VALIDATION_BYTES:
        with open_store(memory=True) as store:
            yield store
        return
    with tempfile.TemporaryDirectory(prefix="stepnc-graph-validate-") as tmp:
        with open_store(Path(tmp) / "store", readonly=False) as store:  # written through .oxigraph
            yield store


