"""The derived layer of a loaded file: what makes its graph pleasant and fast to query.

A file's graph is lossless Part 21 in RDF; it must stay exactly that (the
writer reads it back). Questions like "which workingsteps use a grooving
tool" or "how many tool changes" need facts the lossless form leaves
implicit, so the loader writes them into a second graph,
``<graph>/derived`` (:func:`stepnc_graph.core.naming.derived_graph_iri`), in the
same atomic load, replaced and removed with the file:

* **class closure** -- ``?i a ?super`` for every superclass (ISO supertypes
  and analysis classes such as ``sga:RoughingOperation``) of each instance
  of an ISO 14649 process entity;
* **generic attribute values** -- ``?i attr:its_id ?v`` beside each
  ``stepnc:executable.its_id`` (and the eight other its_id properties), for
  every attribute of those entities (SPARQL does not apply
  ``rdfs:subPropertyOf``);
* **labels** -- ``rdfs:label`` from a non-empty ``its_id``;
* **list positions** -- ``sga:index`` (1-based) on each cell of the lists
  of ISO 14649 attributes;
* **execution order** -- one ``sga:ExecutionStep`` per workingstep in the
  flattened order of the program (:class:`ExecutionOrder`), with
  ``sga:order``, ``sga:executes``, ``sga:workplan``, ``sga:setup``,
  ``sga:next``, ``sga:tool`` and ``sga:toolBefore`` (so a tool change is a
  step whose two differ); and ``sga:feature`` from each workingstep to the
  features it machines;
* **what a row per step shows** -- on each step its program
  (``sga:program``), the #id of its workingstep (``sga:workingstepId``) and
  the #id and class of that workingstep's operation (``sga:operationId``,
  ``sga:operationClass``) and the operation itself (``sga:operation``); the
  names (its_id) of its workingstep, operation, workplan, setup and tool
  (``sga:workingstepName`` ... ``sga:toolName``),
  the tool's #id and its body's class (``sga:toolId``, ``sga:toolBodyClass``),
  and the local names of the two classes (``sga:operationType``, ``sga:toolBodyType``);
  on each manufacturing feature its #id, class and program
  (``sga:featureId``, ``sga:featureClass``, ``sga:featureProgram``), and on it and on each
  operation the local name of its class (``sga:typeName``). The data
  graph holds them too, but reading them there is one index look-up per step
  or thing (or, for the program, one per graph and step); read from the
  layer they are scans the query engine joins by hashing (docs/querying.md,
  "Speed"); a class's local name computed per row (``STRAFTER(STR(?class), "#")``)
  costs a query two string-table look-ups a row, read from the layer one;
* **instance counts** -- one ``sga:ClassCount`` for every class the program's
  graph types instances with: ``sga:countedIn``, ``sga:countedClass`` and
  ``sga:instanceCount`` (the ``instance-counts`` query reads these few
  dozen numbers instead of every instance).

What is *not* derived, to keep loads fast (the target is a load rate at most
15 % below a load without this layer; see ``bench/query_bench.py``): nothing
for instances of the ISO 10303 resource schemas (points, directions,
placements, curves -- most of a real program's instances), of explicit
toolpaths, tolerances and parameters
(:data:`~stepnc_graph.graphs.vocabulary_graph.NOT_DERIVED`), nor for the lists
they hold. The vocabulary graph still answers ``rdfs:subClassOf*`` for them.

The loader's mapper writes the closure, the generic values and the labels
while it maps (:class:`~stepnc_graph.mapping.mapper.DerivedTables`), so they
stream into the layer with the load; so do the list positions and the generic
values that are blank nodes (lists, typed values): the mapper writes every
list cell itself, and those lines go into the store in the same document as
the program's text that holds the nodes
(:class:`~stepnc_graph.store.contract.Joint`), since a blank node's label
holds inside one document only. A load that has no mapper (JSON-LD) gets them
from one CONSTRUCT and walks over ``rdf:List`` chains in Python over a few
SELECTs on the loaded graph instead, as does a store that cannot write blank
nodes (a remote one: SPARQL Update copies them there, and the list positions are
written by the IRIs that name its blank nodes where its answers' labels are such
IRIs, Virtuoso's ``nodeID://``); tests require the ways to give the same layer. The execution order is always read from the loaded
graph (a few SELECTs, and the workplans' lists only when the positions came
with the program's text).

The rules come from :mod:`.derive_rules`, the walks over lists and the execution order from
:mod:`.derive_order`; this module writes the layer.
"""

from __future__ import annotations

import contextlib
import itertools
from concurrent.futures import ThreadPoolExecutor
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.core.naming import (
    ANALYSIS_NS,
    class_count_iri,
    derived_graph_iri,
)
from stepnc_graph.loading.derive_order import ORDER_LISTS, ExecutionOrder, Lists, Reader, Step, values_clause
from stepnc_graph.store.answers import store_label
from stepnc_graph.loading.derive_rules import (
    LAYER_VERSION,
    RDF_NS,
    RDF_TYPE,
    TEXT_PIECE,
    DeriveRules,
    compile_rules,
    edition_rules,
    edition_tables,
    graph_editions,
    integer_literal,
    iso14649_rules,
    sga,
    superclasses,
)

if TYPE_CHECKING:
    from stepnc_graph.store import Store


__all__ = ["LAYER_VERSION", "DerivedLayer", "DeriveRules", "Lists", "Reader", "compile_rules", "derive",
           "edition_rules", "edition_tables", "instance_counts", "iso14649_rules", "superclasses"]


@dataclass
class DerivedLayer:
    """What :func:`derive` wrote: triple count and the flattened order."""

    graph: str
    triples: int
    steps: list[Step]


def derive(store: Store, graph: str, target: Callable[[str], str],
           rules: DeriveRules | None = None, mapped: int | None = None,
           blank_mapped: int | None = None) -> DerivedLayer:
    """Compute the derived layer of the file graph ``graph`` and write it.

    ``target(name)`` is the physical graph to read or write for ``graph`` and
    its derived graph now (a staging graph during an in-memory replacement,
    see :meth:`GraphStore.replace_graph`). ``mapped`` is the number of layer
    triples the loader's mapper already wrote (:class:`DerivedTables`: the
    closure, the generic values that are no blank nodes and the labels); None
    when it wrote none (a JSON-LD load), and then a CONSTRUCT over the graph
    finds them. ``blank_mapped`` is the number of layer lines that name the
    program's blank nodes (list positions, generic values that are lists or
    typed values) the mapper wrote with the program's text
    (:class:`~stepnc_graph.store.contract.Joint`); a store that writes blank
    nodes loaded them, one that cannot did not, and None says the mapper wrote
    none: then the walks below find and write them.
    """
    rules = rules or edition_rules(graph_editions(store, target(graph)))
    reader = Reader(store, target(graph))
    layer = derived_graph_iri(graph)
    capabilities = store.capabilities
    streamed = blank_mapped is not None and capabilities.blank_node_writes
    named = capabilities.blank_node_iri_prefix  # a remote store's labels name its blank nodes
    # with the list positions written, or written by the store itself (a remote store whose
    # labels name no node: one SPARQL Update, below), only the lists the order walks are read
    # (Virtuoso 7.2, 10k instances: every process list's cells took its server 0.2-0.4 CPU-s)
    walked = streamed or (not capabilities.blank_node_writes and not named)
    node = ox.NamedNode(target(layer))
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="stepnc-graph cells") as pool:
        # the positions are written by the labels of the store's answers: the cells are read from
        # the store itself, on a thread, while the walks below may read the client's copy of the
        # program (RemoteStore.own_labels), whose blank nodes are its own
        labelled = pool.submit(_labelled_cells, store, reader, rules) if named else None
        lists = Lists.read(reader, ORDER_LISTS if walked or named else rules.list_properties)
        steps, written = _write_order(store, graph, node, rules, reader, lists, mapped)
        cells = labelled.result() if labelled is not None else lists
    if streamed:
        written += blank_mapped or 0
    elif store.capabilities.blank_node_writes:
        # The quads that hold blank nodes go as quads (a blank node has no name SPARQL or a
        # second text could give it), streamed: in one transaction when few, else in bulk calls
        written += store.add_quads(lists.index_quads(node))
        del lists, cells  # the cells: the largest part of this function's memory
        written += store.add_quads(ox.Quad(s, p, o, node) for s, p, o in reader.select(rules.blank_values))
    else:  # a remote store: blank nodes cannot be written as they are, so the store copies them
        before = store.count(node.value)
        positions = _named_positions(cells, node, named) if named else None
        store.update(_blank_updates(rules, target(graph), node.value, capabilities.join_order_prologue,
                                    positions=positions is None))
        for piece in positions or ():
            store.update(piece)
        written += store.count(node.value) - before
    return DerivedLayer(layer, (mapped or 0) + written, steps)


def _labelled_cells(store: Store, reader: Reader, rules: DeriveRules) -> Lists:
    """The cells of the lists ``rules`` positions, read from ``store`` itself (see :func:`derive`)."""
    with getattr(store, "own_labels", contextlib.nullcontext)():
        return Lists.read(reader, rules.list_properties)


def _write_order(store: Store, graph: str, node: ox.NamedNode, rules: DeriveRules, reader: Reader, lists: Lists,
                 mapped: int | None) -> tuple[list[Step], int]:
    """Write the layer's text into ``node`` (the execution order, the features', operations' and
    instance counts' facts, and, where no mapper wrote them (``mapped`` None), the closure, generic
    values and labels): the flattened order and the lines written."""
    order = ExecutionOrder(reader, rules, lists)
    steps = order.flatten()
    layer = derived_graph_iri(graph)
    written = 0
    if mapped is None:  # no mapper wrote the closure, generic values and labels: find them
        written += _write_text(store, node.value, reader.construct(rules.construct).decode("utf-8").splitlines(True))
    # Text through the bulk loader, in pieces (each bulk load call costs ~0.1 s of file
    # ingestion on disk, whatever its size, and holds memory in proportion to it); the lines
    # are made as they are written (a program of 1M instances has ~300k of them here).
    written += _write_text(store, node.value, itertools.chain(
        order.triples(graph), order.feature_triples(), order.feature_facts(graph), order.operation_facts(graph),
        instance_counts(reader, graph),
        [f"<{layer}> {sga('layerOf')} <{graph}> .\n", f"<{layer}> {sga('layerVersion')} {integer_literal(LAYER_VERSION)} .\n"]))
    return steps, written


def instance_counts(reader: Reader, graph: str) -> Iterator[str]:
    """How many instances (IRIs, not the blank nodes of typed values) the program's graph types
    with each class, as it types them (no superclasses): one ``sga:ClassCount`` per class, with
    ``sga:countedIn``, ``sga:countedClass`` and ``sga:instanceCount``, in the order of the classes'
    IRIs (so a re-load of the same file writes the same lines)."""
    rows = reader.select("SELECT ?c (COUNT(?i) AS ?n) WHERE { ?i a ?c FILTER(isIRI(?i)) } GROUP BY ?c ORDER BY ?c")
    kind, program, counted, count = (sga(n) for n in ("ClassCount", "countedIn", "countedClass", "instanceCount"))
    for index, (cls, n) in enumerate((r for r in rows if isinstance(r[0], ox.NamedNode)), start=1):
        me = f"<{class_count_iri(graph, index)}>"
        yield f"{me} {RDF_TYPE} {kind} .\n"
        yield f"{me} {program} <{graph}> .\n"
        yield f"{me} {counted} {cls} .\n"
        yield f"{me} {count} {integer_literal(int(n.value))} .\n"


def _write_text(store: Store, graph: str, lines: Iterable[str], piece: int = TEXT_PIECE) -> int:
    """Add N-Triples ``lines`` to ``graph`` through the store's bulk loader, in pieces of about
    ``piece`` characters; returns how many lines were written."""
    count = 0
    buffer: list[str] = []
    size = 0
    for line in lines:
        buffer.append(line)
        size += len(line)
        if size >= piece:
            store.add_ntriples(graph, "".join(buffer), bulk=True)
            count += len(buffer)
            buffer.clear()
            size = 0
    if buffer:
        store.add_ntriples(graph, "".join(buffer), bulk=True)
        count += len(buffer)
    return count


#: triples of the list positions an ``INSERT DATA`` request holds (:func:`_named_positions`):
#: Virtuoso 7.2's SPARQL compiler refuses one of more than about 4,990 ("SP030 ... memory exhausted")
NAMED_PIECE = 2000


def _named_positions(lists: Lists, layer: ox.NamedNode, prefix: str, piece: int = NAMED_PIECE) -> list[str] | None:
    """``sga:index`` on every cell of ``lists``, counted as the embedded store counts them
    (:meth:`Lists.index_quads`), as ``INSERT DATA`` requests of ``piece`` triples each, every cell
    written as the IRI its label in the store's answers is (a store whose labels beginning with
    ``prefix`` name its nodes: :attr:`~stepnc_graph.store.contract.Capabilities.blank_node_iri_prefix`);
    None if a cell's label is not of that form (the store then counts the positions itself).

    Linear in the cells: the store's own count (:func:`_blank_updates`) pairs every cell with
    each one before it, ``rdf:rest*`` twice; a generated 20k-instance program's workplan of 370
    steps took Virtuoso 7.2 0.6-0.9 server CPU-s that way, and four times that at twice the length."""
    lines: list[str] = []
    for quad in lists.index_quads(layer):
        label = store_label(quad.subject)
        if label is None or not label.startswith(prefix):
            return None
        try:
            cell = ox.NamedNode(label)
        except ValueError:
            return None
        lines.append(f"{cell} {quad.predicate} {quad.object} .")
    return [f"INSERT DATA {{ GRAPH {layer} {{\n" + "\n".join(lines[start:start + piece]) + "\n} }"
            for start in range(0, len(lines), piece)]


def _blank_updates(rules: DeriveRules, source: str, layer: str, prologue: str = "", positions: bool = True) -> str:
    """The blank-node part of the layer as SPARQL Update, for a remote store: generic values that
    are lists or typed values, and (unless not ``positions``) ``sga:index`` on the cells of the
    process lists.

    Each operation's pattern starts with its ``VALUES`` block (the rules: a few hundred
    properties), so a store joining as written looks each property up; ``prologue`` (the store's
    :attr:`~stepnc_graph.store.contract.Capabilities.join_order_prologue`) opens each operation.
    Virtuoso 7.2 otherwise joined the block last on some data, by a nested loop over every quad
    of the graph: 4.3-7.8 server CPU-s for a 10k-instance program's 1,243 blank values, most of
    a replacement, where joined as written they took 0.05-0.09."""
    where = rules.blank_values.split("WHERE", 1)[1].strip()[1:-1]
    index = ox.NamedNode(ANALYSIS_NS + "index")
    opens = f"{prologue}\n" if prologue else ""
    values = f"{opens}INSERT {{ GRAPH <{layer}> {{ ?s ?q ?o }} }} WHERE {{ GRAPH <{source}> {{ {where} }} }}"
    if not positions:
        return values
    return (f"{values} ;\n"
            f"{opens}INSERT {{ GRAPH <{layer}> {{ ?cell {index} ?n }} }} WHERE {{ {{ SELECT ?cell (COUNT(DISTINCT ?mid) AS ?n) "
            f"WHERE {{ GRAPH <{source}> {{ VALUES ?p {{ {values_clause(rules.list_properties)} }} ?s ?p ?head . "
            f"?head <{RDF_NS}rest>* ?mid . ?mid <{RDF_NS}rest>* ?cell . ?cell <{RDF_NS}first> ?x }} }} "
            f"GROUP BY ?cell }} }}")
