"""The compiled checks run on a data graph: their placeholders expanded with the graph's classes
and hierarchy (:class:`RunContext`), the checks whose focus nodes the graph lacks left out, the
others evaluated by Oxigraph on :data:`CHECK_THREADS` threads, their rows merged in the checks'
order (:func:`run`)."""

from __future__ import annotations

import dataclasses
import functools
import itertools
import os
import re
from concurrent.futures import ThreadPoolExecutor
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.outbound import OutboundRefused, refuse_outbound
from stepnc_graph.validation.engine import CLASS_MARK, DATATYPE_MARK, FOCUS_MARK, P21_NS, SUBCLASS_OF, Check
from stepnc_graph.validation.literals import FOLDED, ILL_TYPED, LITERAL, LITERALS_GRAPH
from stepnc_graph.validation.shapes import IllFormedShapes, subclass_closure


#: one solution of a check: focus node, value, path, its other bindings
Solution = tuple[Any, Any, Any, tuple[tuple[str, Any], ...]]


@dataclass(frozen=True)
class Row:
    """One raw result of a check: the focus node, value and path (pyoxigraph terms), and for a
    SPARQL-based check the solution's other bindings (its message may name them)."""

    check: Check
    focus: ox.NamedNode | ox.BlankNode | ox.Literal
    value: ox.NamedNode | ox.BlankNode | ox.Literal | None
    path: ox.NamedNode | None = None
    bindings: tuple[tuple[str, Any], ...] = ()


class Hierarchy:
    """The data graph's class hierarchy for one run: the compiled one (support files) and the data
    graph's own rdfs:subClassOf triples; individuals the support files type."""

    def __init__(self, subclasses: dict[str, set[str]], individuals: dict[str, set[str]],
                 data_edges: list[tuple[str, str]]) -> None:
        self.subclasses: dict[str, set[str]] = {k: set(v) for k, v in subclasses.items()}
        for sub, sup in data_edges:
            self.subclasses.setdefault(sup, set()).add(sub)
        self.individuals = individuals
        self.extended = bool(data_edges)
        self._closures: dict[str, frozenset[str]] = {}

    def closure(self, cls: str) -> frozenset[str]:
        found = self._closures.get(cls)
        if found is None:
            found = self._closures[cls] = frozenset(subclass_closure(self.subclasses, cls))
        return found

    def typed(self, classes: frozenset[str]) -> list[str]:
        return sorted({i for c in classes for i in self.individuals.get(c, ())})


@dataclass
class RunContext:
    """What the placeholders of a check expand to in one data graph."""

    hierarchy: Hierarchy
    present: set[str]
    literals: bool  # the store holds LITERALS_GRAPH (data loaded by :mod:`.rdfdata`)

    def closures(self, check: Check) -> tuple[frozenset[str], ...]:
        if not self.hierarchy.extended:
            return check.closures
        return tuple(self.hierarchy.closure(c) for c in check.target_classes)

    def focus(self, check: Check, var: str, k: int) -> str | None:
        t = f"?_t{k}"
        parts = [f"{{ {var} a {t} . VALUES {t} {{ {' '.join(sorted(c & self.present))} }} }}"
                 for c in self.closures(check) if c & self.present]
        parts += [re.sub(r"\?this\b", var, p) for p in check.other_targets]
        return " UNION ".join(parts) if parts else None

    def class_test(self, v: str, cls: str, k: int) -> str:
        """``v`` is an instance of ``cls`` (SHACL 2.2.2's class membership): typed with a class of
        its closure that occurs in the data graph (a class no node has cannot type ``v``, and the
        shorter list is what each of ``v``'s types is compared with), or an individual the support
        files type. ``v``'s own types (one, mostly) filtered by the list, not the list joined with
        them as ``VALUES``: the 128 checks of a replicated 100k-instance program, one thread,
        2.09-2.50 -> 2.01-2.44 CPU-s (medians 2.35 -> 2.07)."""
        closure = self.hierarchy.closure(cls)
        named = ", ".join(sorted(c for c in closure & self.present if c.startswith("<")))
        test = f"EXISTS {{ {v} a ?_c{k} . FILTER(?_c{k} IN ({named})) }}" if named else "false"
        individuals = self.hierarchy.typed(closure)
        return f"({test} || {v} IN ({', '.join(individuals)}))" if individuals else test

    def datatype_test(self, v: str, dt: str, k: int) -> str:
        plain = f"(isLiteral({v}) && sameTerm(datatype({v}), {dt}))"
        if not self.literals:
            return plain
        g = f"<{LITERALS_GRAPH}>"
        ill = f"NOT EXISTS {{ GRAPH {g} {{ {dt} {ILL_TYPED} {v} }} }}"
        if dt[1:-1] in FOLDED:  # stored by Oxigraph as xsd:integer: the load noted the original type
            return f"(EXISTS {{ GRAPH {g} {{ {dt} {LITERAL} {v} }} }} && {ill})"
        other = (f"(NOT EXISTS {{ GRAPH {g} {{ ?_d{k} {LITERAL} {v} }} }} || "
                 f"EXISTS {{ GRAPH {g} {{ {dt} {LITERAL} {v} }} }})")
        return f"({plain} && {ill} && {other})"

    def expand(self, check: Check) -> str | None:
        """The check's query for this graph; None when it has no focus node here."""
        counter = itertools.count()
        missing = False

        def focus(m: re.Match[str]) -> str:
            nonlocal missing
            text = self.focus(check, m.group(1), next(counter))
            if text is None:
                missing = True
                return ""
            return text

        query = FOCUS_MARK.sub(focus, check.query)
        if missing:
            return None
        query = CLASS_MARK.sub(lambda m: self.class_test(m.group(1), m.group(2), next(counter)), query)
        return DATATYPE_MARK.sub(lambda m: self.datatype_test(m.group(1), m.group(2), next(counter)), query)


#: Checks run on this many threads: Oxigraph evaluates a query without the GIL, so two cores
#: run two checks at once (measured, 118 checks on 100k instances in memory: 0.59 s on one
#: thread, 0.35 s on two; results identical).
CHECK_THREADS = max(1, min(4, os.cpu_count() or 1))


def refuse_service(checks: list[Check], allow: bool = False) -> None:
    """Raise ShapesError if a check's SPARQL (an sh:sparql constraint's, or one built from a shape)
    would send a request to another server (``SERVICE``), unless ``allow``: every check, whether
    or not the graph has focus nodes for it, so that a shapes file is refused whatever the data."""
    if allow:
        return
    for check in checks:
        try:
            refuse_outbound(_parseable(check.query))
        except OutboundRefused as exc:
            raise IllFormedShapes(f"shape {check.shape}, its {check.constraint} constraint: {exc}") from None


def _parseable(query: str) -> str:
    """A check's query with its placeholders as SPARQL a parser reads: the focus pattern an empty
    group, class and datatype tests ``true``."""
    return DATATYPE_MARK.sub("true", CLASS_MARK.sub("true", FOCUS_MARK.sub("{}", query)))


def run(store: ox.Store, graph: str, checks: list[Check], skip: frozenset[str] = frozenset(),
        hierarchy: tuple[dict[str, set[str]], dict[str, set[str]]] | None = None,
        allow_service: bool = False) -> tuple[list[Row], int]:
    """Run the checks whose targets occur in ``graph``; the rows, and how many checks ran.

    Checks whose :attr:`Check.implied` is in ``skip`` are not run (see :mod:`.implied`).
    ``hierarchy``: the support files' subclasses and typed individuals (class -> nodes).
    They run on :data:`CHECK_THREADS` threads; the rows come in the order of ``checks``
    whatever the threads' timing. A check with a ``SERVICE`` clause is refused (ShapesError)
    unless ``allow_service``."""
    refuse_service(checks, allow_service)
    g = ox.NamedNode(graph)
    with ThreadPoolExecutor(CHECK_THREADS) as pool:
        # the multi-typed test (two counts over the type triples: 0.05-0.1 s at 100k instances)
        # runs beside the query of the classes present and the expanding of the checks
        multi = pool.submit(_multi_typed, store, g)
        ctx = _context(store, g, hierarchy)
        todo = _selected(ctx, checks, skip, multi.result)
        evaluate = functools.partial(_evaluate, store, g)
        if len(todo) < 2 or CHECK_THREADS == 1:  # a thread pool costs more than one small check
            found = [evaluate(item) for item in todo]
        else:
            found = list(pool.map(evaluate, todo))
    rows: list[Row] = []
    seen: set[tuple[str, ...]] = set()
    for (check, _), solutions in zip(todo, found, strict=True):
        times = _multiplicity(store, g, ctx, check) if solutions and check.multiplicity else {}
        for focus_node, value, path, bindings in solutions:
            key = (check.shape, check.constraint, str(check.args), str(check.parent), str(focus_node), str(value),
                   str(path), str(bindings))
            if key not in seen:  # a nested shape's ways to fail can match the same value twice
                seen.add(key)
                rows += [Row(check, focus_node, value, path, bindings)] * times.get(str(focus_node), 1)
    return rows, len(todo)


def _context(store: ox.Store, g: ox.NamedNode,
             hierarchy: tuple[dict[str, set[str]], dict[str, set[str]]] | None) -> RunContext:
    """What the checks' placeholders expand to in ``g``: its classes, its own subclass triples."""
    present = {str(s[0]) for s in store.query("SELECT DISTINCT ?t WHERE { ?s a ?t }", default_graph=g)}  # type: ignore[union-attr]
    edges = [(str(r[0]), str(r[1])) for r in store.query(  # type: ignore[union-attr]
        f"SELECT ?s ?o WHERE {{ ?s {SUBCLASS_OF} ?o FILTER(isIRI(?s) && isIRI(?o)) }}", default_graph=g)]
    subclasses, individuals = hierarchy if hierarchy is not None else ({}, {})
    return RunContext(Hierarchy(subclasses, individuals, edges), present,
                      store.contains_named_graph(ox.NamedNode(LITERALS_GRAPH)))


def _selected(ctx: RunContext, checks: list[Check], skip: frozenset[str],
              multi_typed: Callable[[], bool]) -> list[tuple[Check, str]]:
    """The checks that run, with their queries for this graph, in the checks' order: not those
    the mapping guarantees (``skip``), nor those with no focus node here, nor an sh:not of
    classes that only a node with two types could fail (``multi_typed()`` is asked then)."""
    todo: list[tuple[Check, str]] = []
    for check in checks:
        if check.implied in skip or (check.excludes is not None and not ctx.hierarchy.extended
                                     and not check.excludes & ctx.present and not multi_typed()):
            continue
        query = ctx.expand(check)
        if query is not None:
            todo.append((check, query))
    return todo


def _evaluate(store: ox.Store, g: ox.NamedNode, item: tuple[Check, str]) -> list[Solution]:
    """One check's solutions on ``g``: focus node, value, path and its other bindings."""
    check, query = item
    try:
        results = store.query(query, default_graph=g)
    except (SyntaxError, ValueError, OSError) as exc:
        raise IllFormedShapes(f"{check.shape}: its {check.constraint} check does not run: {exc}") from None
    names = [v.value for v in results.variables]  # type: ignore[union-attr]
    # other named variables tell results apart (sh:lessThan's ?other, sh:uniqueLang's ?lang) and
    # fill a SPARQL constraint's message
    keep = [n for n in names if not n.startswith("_") and n not in ("this", "value", "path")]
    out = []
    for s in results:  # type: ignore[union-attr]
        if s["this"] is None:
            continue
        value = s["value"] if "value" in names else None
        if value is None and check.sparql_node is not None and check.path is None:
            value = s["this"]  # a SPARQL-based result of a node shape: the focus node is the value (5.3.2)
        path = s["path"] if "path" in names else None
        out.append((s["this"], value, path if isinstance(path, ox.NamedNode) else None,
                    tuple((n, s[n]) for n in keep if s[n] is not None)))
    return out


def _multi_typed(store: ox.Store, g: ox.NamedNode) -> bool:
    """Whether a node of ``g`` has two types, the file node (p21:ExchangeStructure, prov:Entity)
    aside: the type triples outnumber their subjects by more than the file nodes' own do. Two
    counts, because a self-join of the type triples (``?s a ?t1 , ?t2``) costs 0.24 CPU-s at 100k
    instances against 0.05."""
    def excess(pattern: str) -> int:
        [row] = store.query(f"SELECT (COUNT(*) AS ?n) (COUNT(DISTINCT ?s) AS ?d) WHERE {{ {pattern} }}",  # type: ignore[misc]
                            default_graph=g)
        return int(row[0].value) - int(row[1].value)

    return excess("?s a ?t") > excess(f"?s a <{P21_NS}ExchangeStructure> , ?t")


def _multiplicity(store: ox.Store, g: ox.NamedNode, ctx: RunContext, check: Check) -> dict[str, int]:
    """How many times each focus node of a nested property shape is reached from the root's."""
    pattern = ctx.expand(dataclasses.replace(check, query=check.multiplicity or ""))
    if not pattern:
        return {}
    rows = store.query(f"SELECT ?this (COUNT(*) AS ?n) WHERE {{ {pattern} }} GROUP BY ?this", default_graph=g)
    return {str(r["this"]): int(r["n"].value) for r in rows}  # type: ignore[union-attr]
