"""Export graphs of the store: RDF serialisations and Part 21.

Exports are deterministic -- the same graph gives the same bytes -- so that a
PLM system diffing two exports of a program sees only real changes. Oxigraph
gives blank nodes random labels when it loads, and dumps in the order of its
internal (hashed) ids, so RDF exports are written here in a canonical order:
the graph's own node, then each instance in ``#id`` order with the blank
nodes hanging off it (its lists and typed values) labelled by the instance and
their place (``_:i12b3``), then the other named subjects sorted.
"""

from __future__ import annotations

import io
import tempfile
from contextlib import contextmanager
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, cast

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError, listed_by, option
from stepnc_graph.core.formats import EXPORT_FORMATS, export_format, export_format_names
from stepnc_graph.generators.context import context
from stepnc_graph.mapping.plans import iso14649_plans
from stepnc_graph.mapping.writer import write_graph
from stepnc_graph.core.naming import P21_NS, listed_graphs, program_graphs
from stepnc_graph.schema.catalog import iso14649
from stepnc_graph.store.contract import Store

#: the export formats' names (:data:`~stepnc_graph.core.formats.EXPORT_FORMATS`)
FORMATS = export_format_names()
QUAD_FORMATS = tuple(f.name for f in EXPORT_FORMATS if f.quads)


class ExportError(StepncGraphError, ValueError):
    """An export that cannot be done as asked (unknown graph, p21 of several graphs, ...)."""


def export(store: Store, fmt: str, graph: str | None = None) -> bytes:
    """Serialise one graph (``graph``) or the store's loaded graphs (``None``) as ``fmt``.

    One rule for every format: without ``graph`` an export holds the graphs a user names -- the
    programs, their link graphs and graphs users added (:func:`~stepnc_graph.core.naming.listed_graphs`) -- never the
    vocabulary graph or the derived layers, which a load writes again (name one with ``graph``
    to export it). Triple formats (ttl, nt, p21) hold one graph, so without ``graph`` they need a
    store of one program (that program's graph); nq, trig and jsonld keep graph names.
    """
    chosen = export_format(fmt)
    if chosen is None:
        raise ExportError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
    if graph is not None and not store.has_graph(graph):
        raise ExportError(f"no graph {graph} in the store")
    if graph is None and chosen.one_graph:
        programs = program_graphs(store)
        if len(programs) != 1:
            raise ExportError(f"{fmt} writes one graph and the store holds {len(programs)} programs; "
                              f"choose one with {option('graph')} ({listed_by()}) or use nq, trig or jsonld")
        graph = programs[0]
    if fmt == "p21":
        assert graph is not None
        return _part21(store, graph)
    graphs = None if graph is not None else listed_graphs(store)
    # the canonical order is read from one dump of each graph: a remote graph is copied here first
    local = store if store.capabilities.local_reads else store.local_copy(graph or graphs)
    if chosen.rdf is None:  # JSON-LD, compacted or framed
        return _jsonld(local, graph, graphs, fmt == "jsonld-tree")
    prefixes = context(iso14649()[0].naming)
    text = "".join(canonical_lines(local, graph, graphs, quads=chosen.quads or graph is None))
    return _serialize(getattr(ox.RdfFormat, chosen.rdf), text, not chosen.quads, prefixes)


def _part21(store: Store, graph: str) -> bytes:
    """The graph as Part 21, read from the text its load kept where the store has one that still
    describes it (:meth:`~stepnc_graph.store.contract.Store.kept_text`), else from the store.

    The kept text costs a fifth of Oxigraph's reading of the quads (a generated 100k-instance
    program: 2.6 CPU-s against 12-14); tests/test_export_kept.py compares both ways on every
    fixture, random and damaged programs."""
    with _kept(store, graph, store_labels=False) as path:  # the writer needs no label of the store's
        if path is not None:
            return write_graph(iso14649_plans(), ox.parse(path=str(path), format=ox.RdfFormat.N_TRIPLES),
                               graph).encode("utf-8")
    return write_graph(iso14649_plans(), store.quads(graph), graph).encode("utf-8")


@contextmanager
def _kept(store: Store, graph: str, store_labels: bool) -> Iterator[Path | None]:
    """The N-Triples file of ``graph`` written from the text its load kept
    (:meth:`~stepnc_graph.store.contract.Store.kept_text`), removed on exit; None when the store
    has none that still describes the graph."""
    with tempfile.TemporaryDirectory(prefix="stepnc-graph-export-") as scratch:
        path = Path(scratch) / "graph.nt"
        yield path if store.kept_text(graph, path, store_labels) else None


def _serialize(fmt: ox.RdfFormat, text: str, triples: bool, prefixes: dict[str, str] | None = None) -> bytes:
    """The canonical N-Quads ``text`` as ``fmt``: N-Triples and N-Quads are that text already
    (Oxigraph's own term syntax, see :func:`canonical_lines`), the others are written by Oxigraph
    from it, in its order."""
    if fmt in (ox.RdfFormat.N_TRIPLES, ox.RdfFormat.N_QUADS):
        return text.encode("utf-8")
    quads = ox.parse(text.encode("utf-8"), ox.RdfFormat.N_QUADS)
    data: Iterator[ox.Quad] | Iterator[ox.Triple] = (
        (ox.Triple(q.subject, q.predicate, q.object) for q in quads) if triples else quads)
    keep = prefixes if prefixes and fmt in (ox.RdfFormat.TURTLE, ox.RdfFormat.TRIG) else None
    buffer = io.BytesIO()
    ox.serialize(data, buffer, fmt, prefixes=keep)
    return buffer.getvalue()


def canonical_quads(store: Store, graph: str | None = None,
                    graphs: list[str] | None = None) -> Iterator[ox.Quad]:
    """The quads of ``graph`` in the canonical order; for None, of ``graphs`` (default: every
    graph, the vocabulary and derived layers included, and the default graph), in IRI order.

    A blank node keeps one label across graphs (a derived layer's ``sga:index`` is on the list
    cells of its program graph), so whole-store labels carry the graph's place as well.
    """
    text = "".join(canonical_lines(store, graph, graphs, quads=True))
    return iter(ox.parse(text.encode("utf-8"), ox.RdfFormat.N_QUADS))


def canonical_lines(store: Store, graph: str | None = None, graphs: list[str] | None = None,
                    quads: bool = True) -> Iterator[str]:
    """:func:`canonical_quads` as N-Quads lines (``quads=False``: N-Triples, for one graph).

    Each graph is read in one call, as Oxigraph's N-Triples (one line a triple, terms in the
    syntax ``str()`` gives them), and ordered here as text: reading it quad by quad, a call into
    the store for every subject, cost more than the load that wrote it (issue 32).
    """
    labels = _Labels()
    if graph is not None:
        yield from _graph_lines(store, graph, labels, "", quads, alone=True)
        return
    if graphs is None:
        default: list[str] = []
        _dump(store, ox.DefaultGraph(), lambda line: default.append(line + "\n"))
        yield from sorted(default)
    for k, name in enumerate(graphs if graphs is not None else store.all_graphs(), start=1):
        yield from _graph_lines(store, name, labels, f"g{k}", quads, alone=False)


class _Lines:
    """A binary sink for Oxigraph's ``dump``: the N-Triples it writes, handed to ``take`` a line
    at a time (without its end of line) as they come, so the text of a large graph is never held
    whole. Only ``\\n`` ends a line: the other line separators Unicode knows stay unescaped
    inside literals."""

    def __init__(self, take: Callable[[str], None]) -> None:
        self.take = take
        self.tail = b""

    def write(self, data: bytes) -> int:
        chunk = self.tail + bytes(data)
        end = chunk.rfind(b"\n")
        if end < 0:
            self.tail = chunk
            return len(data)
        self.tail = chunk[end + 1:]
        for line in chunk[:end].decode("utf-8").split("\n"):
            if line:
                self.take(line)
        return len(data)

    def flush(self) -> None:
        """Nothing is buffered but a partial line (Oxigraph ends every line)."""


def _dump(store: Store, graph: ox.NamedNode | ox.DefaultGraph, take: Callable[[str], None]) -> None:
    """Each line of ``graph`` as Oxigraph writes it in N-Triples, to ``take``. By a CONSTRUCT, which
    costs what Oxigraph's dump costs (a generated 100k-instance program: 11.6-11.9 CPU-s against
    12.1-13.8, the same text), where the dump would need ``store.oxigraph``, which a writer hands out
    only as a database that may then be written through (it then keeps no load's text,
    see :meth:`~stepnc_graph.store.contract.Store.kept_text`)."""
    where = "?s ?p ?o" if isinstance(graph, ox.DefaultGraph) else f"GRAPH {graph} {{ ?s ?p ?o }}"
    triples = store.query(f"CONSTRUCT {{ ?s ?p ?o }} WHERE {{ {where} }}")
    triples.serialize(cast(IO[bytes], _Lines(take)), ox.RdfFormat.N_TRIPLES)


#: a graph's triples as text: subject -> [(predicate, object)], each term as N-Triples writes it
_Triples = dict[str, list[tuple[str, str]]]


def _read_graph(store: Store, graph: str, alone: bool = True) -> tuple[_Triples, list[tuple[int, str]]]:
    """The graph's triples by subject, and its ``p21:id``s as (number, subject); each predicate's
    text is held once (a large graph's index is most of an export's memory).

    Read from the text the graph's load kept where the store has one that still describes it
    (:meth:`~stepnc_graph.store.contract.Store.kept_text`: the loader writes every term as
    Oxigraph writes it back, tests/test_export_kept.py holds it to that), else dumped. Beside
    other graphs (not ``alone``) its blank nodes keep the store's labels, so that a node two
    graphs share (a derived layer's index on a list cell) stays one node."""
    triples: _Triples = {}
    numbered: list[tuple[int, str]] = []
    predicates: dict[str, str] = {}
    id_predicate = f"<{P21_NS}id>"

    def take(line: str) -> None:
        subject, predicate, rest = line.split(" ", 2)
        predicate = predicates.setdefault(predicate, predicate)
        obj = rest[:-2]  # " ."
        triples.setdefault(subject, []).append((predicate, obj))
        if predicate == id_predicate:
            numbered.append((int(obj[1:obj.index('"', 1)]), subject))

    with _kept(store, graph, store_labels=not alone) as path:
        if path is None:
            _dump(store, ox.NamedNode(graph), take)
        else:
            lines = _Lines(take)
            with open(path, "rb") as fh:
                while data := fh.read(1 << 20):
                    lines.write(data)
    numbered.sort()
    return triples, numbered


class _Labels:
    """Canonical blank node labels: ``_:<scope><root>b<n>``, one per node for a whole export."""

    def __init__(self) -> None:
        self.of: dict[str, str] = {}
        self.used: dict[str, int] = {}

    def label(self, term: str, prefix: str) -> str:
        if not term.startswith("_:"):
            return term
        if term not in self.of:
            self.used[prefix] = self.used.get(prefix, 0) + 1
            self.of[term] = f"_:{prefix}b{self.used[prefix]}"
        return self.of[term]


def _graph_lines(store: Store, graph: str, labels: _Labels, scope: str, quads: bool, alone: bool) -> Iterator[str]:
    """The graph's lines in the canonical order: its own node, its instances by ``#id``, its
    other named subjects by IRI, each with the blank nodes it reaches; then the blank subjects
    none reaches. ``alone``: the export holds this graph only (see :func:`_read_graph`)."""
    triples, numbered = _read_graph(store, graph, alone)
    g = f"<{graph}>"
    end = f" {g} .\n" if quads else " .\n"
    roots: list[tuple[str, str]] = [("g", g)] + [(f"i{number}", node) for number, node in numbered]
    taken = {node for _, node in roots}
    others = sorted(node for node in triples if node.startswith("<") and node not in taken)
    roots += [(f"n{k}", node) for k, node in enumerate(others, start=1)]
    seen: set[str] = set()
    for prefix, node in roots:
        yield from _subtree(triples, scope + prefix, node, seen, labels, end)
    # blank subjects no named subject of this graph reaches: the cells a derived layer indexes
    # (labelled in their program graph), or what SPARQL Update added (labelled by content)
    rest = {node for node in triples if node.startswith("_:") and node not in seen}
    known = sorted((n for n in rest if n in labels.of), key=lambda n: labels.of[n])
    unknown = sorted((n for n in rest if n not in labels.of), key=lambda n: _deep(triples, n))
    for node in known + unknown:
        if node not in seen:
            yield from _subtree(triples, scope + "x", node, seen, labels, end)


def _subtree(triples: _Triples, prefix: str, root: str, seen: set[str], labels: _Labels,
             end: str) -> Iterator[str]:
    """``root``'s triples sorted, then its blank objects' (depth first), relabelled ``_:<prefix>b<n>``."""
    if root.startswith("_:"):
        seen.add(root)
        labels.label(root, prefix)
    stack = [root]
    while stack:
        subject = stack.pop()
        pairs = triples.get(subject, [])
        if len(pairs) > 1:
            pairs = sorted(pairs, key=lambda po: _pair_key(triples, po))
        children = []
        for _, obj in pairs:
            if obj.startswith("_:") and obj not in seen:
                seen.add(obj)
                labels.label(obj, prefix)
                children.append(obj)
        label = labels.label(subject, prefix)
        for predicate, obj in pairs:
            yield f"{label} {predicate} {labels.label(obj, prefix)}{end}"
        stack.extend(reversed(children))


def _pair_key(triples: _Triples, pair: tuple[str, str]) -> tuple[str, int, str]:
    """A subject's triples' order: by predicate IRI, then named objects and literals by their
    text, then blank objects by their own triples (:func:`_shallow`)."""
    predicate, obj = pair
    if obj.startswith("_:"):
        return (predicate[1:-1], 1, _shallow(triples, obj))
    return (predicate[1:-1], 0, obj)


def _deep(triples: _Triples, node: str, limit: int = 500) -> str:
    """A blank node's content down through its blank objects, without labels (up to ``limit``
    nodes): orders the blank subjects no named subject reaches, such as OWL's
    ``[ a owl:AllDisjointClasses ; owl:members (...) ]``."""
    lines: list[str] = []
    stack: list[tuple[str, str]] = [("", node)]
    visited = 0
    while stack and visited < limit:
        path, current = stack.pop()
        visited += 1
        for predicate, obj in sorted(triples.get(current, []), key=lambda po: (po[0][1:-1], po[1])):
            if obj.startswith("_:"):
                stack.append((f"{path}/{predicate[1:-1]}", obj))
            else:
                lines.append(f"{path} {predicate} {obj}")
    return "\n".join(sorted(lines))


def _shallow(triples: _Triples, term: str) -> str:
    """A blank node's own triples without blank labels: orders blank siblings (SET members that
    are typed values) the same way whatever labels Oxigraph gave them."""
    if not term.startswith("_:"):
        return ""
    return "\n".join(sorted(f"{p} {'[]' if o.startswith('_:') else o}" for p, o in triples.get(term, [])))


def _jsonld(store: Store, graph: str | None, graphs: list[str] | None, tree: bool = False) -> bytes:
    """JSON-LD compacted with the generated context (``tree``: a readable, framed tree); see
    :mod:`stepnc_graph.exporting.jsonld`."""
    from stepnc_graph.exporting.jsonld import export_jsonld

    # a JSON-LD document of the store is its programs (and links), what a PLM system takes
    return export_jsonld(canonical_quads(store, graph, graphs), graph, tree)
