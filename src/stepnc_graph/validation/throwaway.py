"""The throw-away store ``validate FILE`` loads files into: in memory, or on disk when they are
large; what goes into it beside the program graphs (the shapes graph, when a check reads
``$shapesGraph``) and what may be left out of them (the position triples, when no check reads
them)."""

from __future__ import annotations

import re
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.naming import DATA_BASE
from stepnc_graph.validation.compiled import CompiledShapes
from stepnc_graph.validation.engine import SHAPES_GRAPH, Check
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


#: ``p21:id`` or ``p21:line`` in a query, as a full IRI or prefixed (any prefix: erring on the side of keeping them)
_POSITION_TERM = re.compile(r"(?:p21#|:)(?:id|line)\b")


def reads_positions(checks: Sequence[Check]) -> bool:
    """Whether a check (an organisation's own SPARQL, say) may read ``p21:id``/``p21:line``: it
    names them, reads any predicate (a variable in predicate position), or is ``sh:closed``. Then
    the throw-away graph keeps those triples; otherwise their lines come from the load (a sixth
    fewer triples to insert; 100k instances, end to end, medians in one quiet hour: 4.2 s with
    them, 3.5-3.8 s without)."""
    return any(_POSITION_TERM.search(c.query) or c.constraint == "closed"
               or (c.sparql_node is not None and _ANY_PREDICATE.search(_PROJECTION.sub("SELECT ", c.query)))
               for c in checks)


#: a triple pattern whose predicate is a variable: a variable after a subject (a variable, an IRI,
#: a blank node's label, the end of a ``[...]``) and before an object (any term); after a ``)`` (a
#: collection, or a FILTER's end before a pattern) only before a variable or a literal. Broad on
#: purpose: a false match (``GROUP BY ?a ?b ?c``) only keeps every triple in the graph
_ANY_PREDICATE = re.compile(r"(?:[?$]\w+|<[^>\s]*>|_:\w+|\])\s+[?$]\w+\s+[^\s.;,}]"
                            r"|\)\s+[?$]\w+\s+(?!a\s)[^\s.;,}<]")
#: a SELECT's projection (``SELECT DISTINCT ?this ?item ?dim``: three variables, no triple pattern)
_PROJECTION = re.compile(r"\bSELECT\b[^{]*?(?=\bWHERE\b|\{)", re.IGNORECASE)


def properties_read(checks: Sequence[Check]) -> frozenset[str] | None:
    """The properties (bare IRIs) that the checks which may run on a graph the Part 21 mapping
    wrote can read: every IRI their queries name (:mod:`.implied`: the checks it guarantees run
    only when the graph lacks the guarantee, and the load then writes every attribute). None when
    a check may read a property it does not name: a variable or negated predicate, ``sh:closed``,
    prefixed names or a base IRI. The throw-away graph then leaves the other attributes out (a
    quarter of a replicated real program's triples: placement names, its_ids, coordinates)."""
    found: set[str] = set()
    for c in checks:
        if c.implied is not None:  # run only when the graph lacks the guarantee: then it holds everything
            continue
        text = " ".join([c.query, c.path or "", c.multiplicity or "", *c.other_targets])
        if c.constraint == "closed" or _UNNAMED.search(text) or _ANY_PREDICATE.search(_PROJECTION.sub("SELECT ", text)):
            return None
        found.update(_IRI.findall(text))
    return frozenset(found)


#: an IRI in a query
_IRI = re.compile(r"<([^<>\s]*)>")
#: what lets a query read a property it does not write out: a negated property set (``!<p>``,
#: ``!^<p>``, ``!a``, ``!(...)`` of those), a PREFIX or BASE declaration, a predicate after ``;``
_UNNAMED = re.compile(r"!\s*(?:\(\s*)?(?:<|\^|a\b)|\b(?:PREFIX|BASE)\b|;\s*[?$]\w+\s", re.IGNORECASE)


#: Input above this size is validated in a temporary on-disk store instead of memory: Oxigraph's
#: in-memory store holds about 70 bytes of RAM per byte of Part 21 (measured: 1M instances, 63 MB,
#: peaked at 4.4 GB), its on-disk store keeps a bounded cache. Below it, memory is faster (100k
#: instances, 6 MB: 3.6 s against 5.7 s to load).
MEMORY_VALIDATION_BYTES = 16_000_000


#: Input below this size is loaded whole: working out which attributes no check reads
#: (:func:`properties_read`) takes some 60 ms of pattern matching over the shipped checks at each
#: validation, more than leaving them out saves on a small program (in-process, medians of 5: the
#: 89-instance example 141 ms against 79 loaded whole; a replicated real program of 1k instances,
#: 61 KB, 192 against 161; of 10k, 605 KB, 1,080 against 1,060; of 100k, 6.3 MB, 35 % fewer
#: triples to insert). Read as ``throwaway.HOLD_BYTES`` when validating, so a test may set it.
HOLD_BYTES = 1_000_000


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


