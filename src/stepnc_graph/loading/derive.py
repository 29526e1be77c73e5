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
  ``sga:operationClass``). The data graph holds them too, but reading them
  there is one index look-up per step (or, for the program, one per graph
  and step); read from the steps they are scans the query engine joins by
  hashing. The library's row-per-step queries take a third to a half of the
  time they took with look-ups (docs/querying.md, "Speed");
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
stream into the layer with the load; a load that has no mapper (JSON-LD)
gets them from one CONSTRUCT over the loaded graph instead, and a test
requires both ways to give the same layer. The list positions and the order
need walks over ``rdf:List`` chains, done in Python over a few SELECTs, as
are generic values that are blank nodes.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.mapping.editions import SHIPPED, check_edition, edition_terms
from stepnc_graph.mapping.mapper import DerivedTables
from stepnc_graph.mapping.ntriples import RDFS_LABEL
from stepnc_graph.core.naming import (
    ANALYSIS_NS,
    P21_NS,
    STEPNC_NS,
    Naming,
    class_count_iri,
    derived_graph_iri,
    execution_step_iri,
    generic_attribute_iri,
)
from stepnc_graph.schema.model import AggregateType, TypeRef
from stepnc_graph.schema.view import SchemaModel
from stepnc_graph.vocabulary.analysis import ANALYSIS_CLASSES, derived_entities

if TYPE_CHECKING:
    from stepnc_graph.store import Store

RDF_NS = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
RDF_TYPE = f"<{RDF_NS}type>"
RDF_FIRST = ox.NamedNode(RDF_NS + "first")
RDF_REST = ox.NamedNode(RDF_NS + "rest")
XSD_INTEGER = "http://www.w3.org/2001/XMLSchema#integer"
#: the layer's format: what the library queries expect to find (``sga:layerVersion`` on the layer).
#: 2: steps carry their program, workingstep #id, operation #id and class; class counts
LAYER_VERSION = 2
#: characters of layer text per bulk-load call: the store's own batch (see store.tuning.BATCH_CHARS)
TEXT_PIECE = 12_000_000

#: Program structures whose members run in a given order (a LIST) or in no
#: stated order (a SET: flattened in #id order), and single-valued branches.
_ORDERED = {"workplan": "its_elements"}
_UNORDERED = {"parallel": "branches", "non_sequential": "its_elements", "selective": "its_elements"}
_BRANCHES = {"if_statement": ("true_branch", "false_branch"), "while_statement": ("body",)}


def _sga(name: str) -> str:
    return f"<{ANALYSIS_NS}{name}>"


def _integer(n: int) -> str:
    return f'"{n}"^^<{XSD_INTEGER}>'


@dataclass(frozen=True)
class DeriveRules:
    """The model-dependent part of the derivation, compiled once per process.

    ``construct`` is the CONSTRUCT of closure, generic values and labels
    (``blank_values`` selects the generic values that are blank nodes);
    ``list_properties`` the ISO 14649 attributes whose values are
    ``rdf:List`` s; ``workingsteps`` / ``structures`` the classes of
    executables the order walk tells apart.
    """

    construct: str
    blank_values: str
    list_properties: tuple[str, ...]
    workingsteps: frozenset[str]
    structures: frozenset[str]
    operation_properties: tuple[str, ...]
    tool_properties: tuple[str, ...]
    executables: tuple[str, ...]
    superclasses: dict[str, tuple[str, ...]] = field(compare=False)
    generic: dict[str, str] = field(compare=False)
    labels: frozenset[str] = field(compare=False, default=frozenset())

    def tables(self) -> DerivedTables:
        """The part of the layer the loader's mapper writes as it maps (closure, generic values, labels)."""
        return DerivedTables(self.superclasses, self.generic, self.labels, frozenset(self.list_properties),
                             ANALYSIS_NS + "index")


def _is_a(model: SchemaModel) -> dict[str, set[str]]:
    """class -> its direct superclasses: EXPRESS supertypes and the analysis classes.

    SELECTs are left out: the vocabulary makes their members subclasses (so
    ``rdfs:subClassOf*`` lists what an attribute admits), but an instance is
    not counted "as a" speed_select_type; that stays a vocabulary question.
    A plain dict, not a networkx graph: every load computes this, and importing
    networkx would add a tenth of a second to each command.
    """
    parents: dict[str, set[str]] = {e.name: set(e.supertypes) for e in model.entities.values()}
    for c in ANALYSIS_CLASSES:
        for member in c.members:
            parents.setdefault(member, set()).add("sga:" + c.name)
    return parents


def _ancestors(parents: dict[str, set[str]], name: str) -> set[str]:
    """Every class above ``name`` (the supertype graph is acyclic; each class visited once)."""
    found: set[str] = set()
    stack = list(parents.get(name, ()))
    while stack:
        current = stack.pop()
        if current not in found:
            found.add(current)
            stack.extend(parents.get(current, ()))
    return found


def _is_list(model: SchemaModel, t: TypeRef) -> bool:
    """Whether values of ``t`` are ``rdf:List`` s: an aggregate other than a top-level SET
    (:mod:`stepnc_graph.vocabulary.typemap`'s rule, without importing rdflib into every load)."""
    base = model.base_type(t)
    return isinstance(base, AggregateType) and base.kind != "SET"


def _iri(naming: Naming, name: str) -> str:
    return f"<{ANALYSIS_NS}{name[4:]}>" if name.startswith("sga:") else f"<{naming.declaration_iri(name)}>"


def compile_rules(model: SchemaModel, naming: Naming) -> DeriveRules:
    """Tables of the derivation for ``model``: which classes, properties and lists count."""
    derived = derived_entities(model)
    entities = [e for e in model.entities.values() if e.name in derived]
    is_a = _is_a(model)
    closure = {e.name: tuple(sorted(_ancestors(is_a, e.name))) for e in entities}
    generic: dict[str, str] = {}
    lists: list[str] = []
    labels: list[str] = []
    for e in entities:
        for a in e.explicit:
            prop = naming.attribute_iri(e.name, a.name)
            generic[prop] = generic_attribute_iri(a.name)
            if _is_list(model, a.type):
                lists.append(prop)
            if a.name == "its_id":
                labels.append(prop)
    superclasses = {naming.declaration_iri(c): tuple(_iri(naming, s)[1:-1] for s in ss) for c, ss in closure.items()}
    construct, blank_values = _layer_queries(generic, superclasses, labels)
    executable = set(model.all_subtypes("executable"))
    return DeriveRules(
        construct=construct,
        blank_values=blank_values,
        list_properties=tuple(sorted(lists)),
        workingsteps=frozenset(n for n in executable if model.is_subtype(n, "workingstep")),
        structures=frozenset(n for n in executable if model.is_subtype(n, "program_structure")),
        operation_properties=tuple(sorted(p for p, g in generic.items() if g.endswith("#its_operation"))),
        tool_properties=tuple(sorted(p for p, g in generic.items() if g.endswith("#its_tool"))),
        executables=tuple(sorted(n for n in executable if not model.entity(n).abstract)),
        superclasses=superclasses,
        generic=generic,
        labels=frozenset(labels),
    )


def _layer_queries(generic: dict[str, str], superclasses: dict[str, tuple[str, ...]],
                   labels: Iterable[str]) -> tuple[str, str]:
    """The CONSTRUCT of closure, generic values and labels, and the SELECT of the generic values
    that are blank nodes (see :class:`DeriveRules`), for these tables (IRIs)."""
    pairs = " ".join(f"(<{p}> <{g}>)" for p, g in sorted(generic.items()))
    supers = " ".join(f"(<{c}> <{s}>)" for c, ss in sorted(superclasses.items()) for s in ss)
    # Blank nodes (list heads, typed values) cannot travel as N-Triples text:
    # Oxigraph gives each parsed document fresh blank nodes. So values that are
    # blank nodes are selected apart (``blank_values``) and written as quads.
    construct = (
        f"CONSTRUCT {{ ?s ?q ?o }} WHERE {{\n"
        f"  {{ VALUES (?p ?q) {{ {pairs} }} ?s ?p ?o FILTER(!isBlank(?o)) }}\n"
        f"  UNION {{ VALUES (?c ?o) {{ {supers} }} ?s a ?c BIND({RDF_TYPE} AS ?q) }}\n"
        f"  UNION {{ VALUES ?p {{ {' '.join(f'<{p}>' for p in sorted(labels))} }} ?s ?p ?o "
        f"FILTER(STRLEN(?o) > 0) BIND({RDFS_LABEL} AS ?q) }}\n}}")
    blank_values = f"SELECT ?s ?q ?o WHERE {{ VALUES (?p ?q) {{ {pairs} }} ?s ?p ?o FILTER(isBlank(?o)) }}"
    return construct, blank_values


@lru_cache(maxsize=4)
def edition_rules(editions: frozenset[str]) -> DeriveRules:
    """The rules for a graph holding instances of ``editions``: the shipped rules, with the
    closure and generic properties of each edition's own terms (:func:`edition_tables`)."""
    rules = iso14649_rules()
    supers, generic = dict(rules.superclasses), dict(rules.generic)
    for edition in sorted(editions - {SHIPPED}):
        tables = edition_tables(edition)
        supers.update(tables.superclasses)
        generic.update(tables.generic)
    if supers == rules.superclasses and generic == rules.generic:
        return rules
    construct, blank_values = _layer_queries(generic, supers, rules.labels)
    return dataclasses.replace(rules, construct=construct, blank_values=blank_values, superclasses=supers,
                               generic=generic)


def graph_editions(store: Store, graph: str) -> frozenset[str]:
    """The editions a loaded graph's instances were read in (``p21:edition`` on it and on them)."""
    rows = store.query(f"SELECT DISTINCT ?e WHERE {{ GRAPH <{graph}> {{ ?s <{P21_NS}edition> ?e }} }}")
    return frozenset(str(r[0].value) for r in rows)


@lru_cache(maxsize=1)
def iso14649_rules() -> DeriveRules:
    """The rules for the shipped ISO 14649 model."""
    from stepnc_graph.schema.catalog import iso14649

    catalog, model = iso14649()
    return compile_rules(model, catalog.naming)


@lru_cache(maxsize=4)
def edition_tables(edition: str) -> DerivedTables:
    """The derived layer's tables (:class:`~stepnc_graph.mapping.mapper.DerivedTables`) for programs
    of ``edition``: the shipped ones, with the edition's classes closed over their 2002 counterpart
    and the edition's own properties given their generic ``attr:`` property."""
    tables = iso14649_rules().tables()
    if check_edition(edition) == SHIPPED:
        return tables
    supers = dict(tables.superclasses)
    generic = dict(tables.generic)
    for term in edition_terms(edition):
        if term.plan is None:
            continue
        if term.slot is not None:
            generic[term.iri] = generic_attribute_iri(term.slot.name)
        elif term.shipped is not None and term.shipped in supers:
            supers[term.iri] = (term.shipped, *supers[term.shipped])
    return dataclasses.replace(tables, superclasses=supers, generic=generic)


# -- reading the loaded graph --------------------------------------------------


Term = ox.NamedNode | ox.BlankNode | ox.Literal | ox.Triple


class _Reader:
    """SELECTs over the graph being loaded (its physical name may be a staging graph)."""

    def __init__(self, store: Store, source: str) -> None:
        self.store = store
        self.graph = ox.NamedNode(source)

    def select(self, query: str) -> Iterable[ox.QuerySolution]:
        result = self.store.query(query, default_graph=[self.graph])
        assert isinstance(result, ox.QuerySolutions)
        return result

    def construct(self, query: str) -> bytes:
        result = self.store.query(query, default_graph=[self.graph])
        if isinstance(result, list):  # a remote store's CONSTRUCT: Triples
            return ox.serialize(result, format=ox.RdfFormat.N_TRIPLES) or b""
        assert isinstance(result, ox.QueryTriples)
        return result.serialize(format=ox.RdfFormat.N_TRIPLES) or b""


def _values(iris: Iterable[str]) -> str:
    return " ".join(f"<{i}>" for i in iris)


@dataclass
class Lists:
    """The cells of the process lists of a graph: first/rest of each, and each list's members."""

    first: dict[Term, Term]
    rest: dict[Term, Term]

    @classmethod
    def read(cls, reader: _Reader, properties: tuple[str, ...]) -> "Lists":
        """Cells of the lists ``properties`` hold, nested lists included.

        The cells along each list (``rdf:rest*``) first; only when a member is a blank node (a
        nested list, or a typed value) are the members walked into as well, ``(rdf:rest|
        rdf:first)*``: that path visits every member too, and took twice as long on a program
        whose process lists hold instances only (0.23 against 0.13 CPU-s for 2,373 cells at
        10k instances, on the critical path of every load)."""
        lists = cls._select(reader, properties, f"<{RDF_NS}rest>*")
        if any(isinstance(member, ox.BlankNode) for member in lists.first.values()):
            lists = cls._select(reader, properties, f"(<{RDF_NS}rest>|<{RDF_NS}first>)*")
        return lists

    @classmethod
    def _select(cls, reader: _Reader, properties: tuple[str, ...], path: str) -> "Lists":
        rows = reader.select(
            f"SELECT ?cell ?first ?rest WHERE {{ VALUES ?p {{ {_values(properties)} }} "
            f"?s ?p ?head . ?head {path} ?cell . ?cell <{RDF_NS}first> ?first ; <{RDF_NS}rest> ?rest }}")
        lists = cls({}, {})
        for cell, head, tail in rows:
            lists.first[cell] = head
            lists.rest[cell] = tail
        return lists

    def _chain(self, head: Term) -> list[Term]:
        """The cells of the list starting at ``head``, in order (stops on a repeated cell)."""
        out: list[Term] = []
        cell = head
        seen: set[Term] = set()
        while cell in self.first and cell not in seen:
            seen.add(cell)
            out.append(cell)
            cell = self.rest[cell]
        return out

    def members(self, head: Term) -> list[Term]:
        return [self.first[cell] for cell in self._chain(head)]

    def index_quads(self, graph: ox.NamedNode) -> Iterator[ox.Quad]:
        """``sga:index`` on every cell, counted from each list's head (one at a time: a program
        of 1M instances has some 240k cells)."""
        tails = set(self.rest.values())
        index = ox.NamedNode(ANALYSIS_NS + "index")
        for head in self.first:
            if head not in tails:
                for position, cell in enumerate(self._chain(head), start=1):
                    yield ox.Quad(cell, index, ox.Literal(position), graph)  # type: ignore[arg-type]


@dataclass
class Step:
    """One place in the execution order."""

    order: int
    workingstep: ox.NamedNode
    workplan: ox.NamedNode | None
    setup: ox.NamedNode | None
    root: int


class ExecutionOrder:
    """The flattened execution order of a program, from its program structures.

    Roots are the projects' main workplans in #id order (or, in a file
    without a project, the program structures no other one contains).
    Workplans contribute their elements in list order; ``parallel``,
    ``non_sequential`` and ``selective`` their members in #id order (a SET
    has none); ``if_statement`` its true then false branch; a
    ``while_statement`` its body once. The setup of a step is that of the
    nearest enclosing workplan naming one. A structure that contains itself
    is not entered again.
    """

    def __init__(self, reader: _Reader, rules: DeriveRules, lists: Lists) -> None:
        self.rules = rules
        self.lists = lists
        self.kind: dict[ox.NamedNode, str] = {}
        self.ids: dict[ox.NamedNode, int] = {}
        for x, c, i in reader.select(
                f"SELECT ?x ?c ?id WHERE {{ VALUES ?c {{ {_values(STEPNC_NS + n for n in rules.executables)} }} "
                f"?x a ?c ; <{P21_NS}id> ?id }}"):
            self.kind[x] = c.value[len(STEPNC_NS):]
            self.ids[x] = int(i.value)
        self.edges: dict[tuple[ox.NamedNode, str], list[Term]] = defaultdict(list)
        names = [f"{STEPNC_NS}{e}.{a}" for e, a in _ORDERED.items()] + \
                [f"{STEPNC_NS}{e}.{a}" for e, a in _UNORDERED.items()] + \
                [f"{STEPNC_NS}{e}.{a}" for e, bs in _BRANCHES.items() for a in bs] + \
                [f"{STEPNC_NS}{p}" for p in ("workplan.its_setup", "project.main_workplan",
                                              "machining_workingstep.its_feature",
                                              "turning_workingstep.its_features")]
        for s, p, o in reader.select(f"SELECT ?s ?p ?o WHERE {{ VALUES ?p {{ {_values(names)} }} ?s ?p ?o }}"):
            self.edges[(s, p.value[len(STEPNC_NS):])].append(o)
        self.tool: dict[Term, Term] = {}  # workingstep -> the tool of its operation
        for ws, tool in reader.select(
                f"SELECT ?ws ?tool WHERE {{ VALUES ?p {{ {_values(rules.operation_properties)} }} "
                f"VALUES ?q {{ {_values(rules.tool_properties)} }} ?ws ?p ?op . ?op ?q ?tool }}"):
            self.tool[ws] = tool
        #: workingstep -> the #id and the classes (as typed in the program's graph) of its operation
        self.operation: dict[Term, tuple[int, list[Term]]] = {}
        for ws, cls, ident in reader.select(
                f"SELECT ?ws ?c ?id WHERE {{ VALUES ?p {{ {_values(rules.operation_properties)} }} "
                f"?ws ?p ?op . ?op a ?c ; <{P21_NS}id> ?id }}"):
            self.operation.setdefault(ws, (int(ident.value), []))[1].append(cls)
        self.steps: list[Step] = []

    def one(self, node: ox.NamedNode, prop: str) -> Term | None:
        values = self.edges.get((node, prop))
        return values[0] if values else None

    def roots(self) -> list[ox.NamedNode]:
        projects = sorted(((s, o[0]) for (s, p), o in self.edges.items() if p == "project.main_workplan"),
                          key=lambda so: self.ids.get(so[1], 0))  # type: ignore[arg-type]
        if projects:
            return [o for _, o in projects if isinstance(o, ox.NamedNode)]
        contained = {m for n in self.kind for m in self.children(n)}
        return sorted((n for n, k in self.kind.items() if k in self.rules.structures and n not in contained),
                      key=lambda n: self.ids[n])

    def children(self, node: ox.NamedNode) -> list[ox.NamedNode]:
        kind = self.kind.get(node)
        out: list[Term] = []
        if kind in _ORDERED:
            head = self.one(node, f"{kind}.{_ORDERED[kind]}")
            out = self.lists.members(head) if head is not None else []
        elif kind in _UNORDERED:
            out = sorted(self.edges.get((node, f"{kind}.{_UNORDERED[kind]}"), []),
                         key=lambda n: self.ids.get(n, 0))  # type: ignore[arg-type]
        elif kind in _BRANCHES:
            out = [b for a in _BRANCHES[kind] if (b := self.one(node, f"{kind}.{a}")) is not None]
        return [n for n in out if isinstance(n, ox.NamedNode)]

    def flatten(self) -> list[Step]:
        for number, root in enumerate(self.roots()):
            self._walk(root, None, None, number, [])
        return self.steps

    def _walk(self, node: ox.NamedNode, workplan: ox.NamedNode | None, setup: ox.NamedNode | None,
              root: int, stack: list[ox.NamedNode]) -> None:
        kind = self.kind.get(node)
        if kind in self.rules.workingsteps:
            self.steps.append(Step(len(self.steps) + 1, node, workplan, setup, root))
            return
        if kind not in self.rules.structures or node in stack:
            return
        if kind == "workplan":
            own = self.one(node, "workplan.its_setup")
            setup = own if isinstance(own, ox.NamedNode) else setup
        stack.append(node)
        for child in self.children(node):
            self._walk(child, node, setup, root, stack)
        stack.pop()

    def triples(self, graph: str) -> Iterator[str]:
        """The N-Triples lines of the execution steps, one at a time."""
        iri = [f"<{execution_step_iri(graph, s.order)}>" for s in self.steps]
        cls = _sga("ExecutionStep")
        order, executes, workplan, setup, nxt, tool, before = (
            _sga(n) for n in ("order", "executes", "workplan", "setup", "next", "tool", "toolBefore"))
        program, ws_id, op_id, op_class = (
            _sga(n) for n in ("program", "workingstepId", "operationId", "operationClass"))
        graph_node = f"<{graph}>"
        spindle: Term | None = None  # the tool of the last step that had one
        for i, s in enumerate(self.steps):
            me = iri[i]
            yield f"{me} {RDF_TYPE} {cls} .\n"
            yield f"{me} {order} {_integer(s.order)} .\n"
            yield f"{me} {executes} {s.workingstep} .\n"
            yield f"{me} {program} {graph_node} .\n"
            yield f"{me} {ws_id} {_integer(self.ids[s.workingstep])} .\n"
            if (operation := self.operation.get(s.workingstep)) is not None:
                yield f"{me} {op_id} {_integer(operation[0])} .\n"
                yield from (f"{me} {op_class} {c} .\n" for c in operation[1])
            if s.workplan is not None:
                yield f"{me} {workplan} {s.workplan} .\n"
            if s.setup is not None:
                yield f"{me} {setup} {s.setup} .\n"
            if i > 0 and self.steps[i - 1].root != s.root:
                spindle = None  # another project: its first tool is a load, not a change
            if spindle is not None:
                yield f"{me} {before} {spindle} .\n"
            used = self.tool.get(s.workingstep)
            if isinstance(used, ox.NamedNode):
                yield f"{me} {tool} {used} .\n"
                spindle = used
            if i + 1 < len(self.steps) and self.steps[i + 1].root == s.root:
                yield f"{me} {nxt} {iri[i + 1]} .\n"

    def feature_triples(self) -> Iterator[str]:
        """``sga:feature`` from each workingstep to the features it machines, one line at a time."""
        feature = _sga("feature")
        for node in sorted(self.kind, key=lambda n: self.ids[n]):
            single = self.one(node, "machining_workingstep.its_feature")
            many = self.one(node, "turning_workingstep.its_features")
            targets = ([single] if single is not None else []) + (self.lists.members(many) if many else [])
            for t in targets:
                if isinstance(t, ox.NamedNode):
                    yield f"{node} {feature} {t} .\n"


# -- writing -------------------------------------------------------------------


@dataclass
class DerivedLayer:
    """What :func:`derive` wrote: triple count and the flattened order."""

    graph: str
    triples: int
    steps: list[Step]


def derive(store: Store, graph: str, target: Callable[[str], str],
           rules: DeriveRules | None = None, mapped: int | None = None) -> DerivedLayer:
    """Compute the derived layer of the file graph ``graph`` and write it.

    ``target(name)`` is the physical graph to read or write for ``graph`` and
    its derived graph now (a staging graph during an in-memory replacement,
    see :meth:`GraphStore.replace_graph`). ``mapped`` is the number of layer
    triples the loader's mapper already wrote (:class:`DerivedTables`: the
    closure, the generic values that are no blank nodes and the labels); None
    when it wrote none (a JSON-LD load), and then a CONSTRUCT over the graph
    finds them.
    """
    rules = rules or edition_rules(graph_editions(store, target(graph)))
    reader = _Reader(store, target(graph))
    layer = derived_graph_iri(graph)
    lists = Lists.read(reader, rules.list_properties)
    order = ExecutionOrder(reader, rules, lists)
    steps = order.flatten()
    node = ox.NamedNode(target(layer))
    written = 0
    if mapped is None:  # no mapper wrote the closure, generic values and labels: find them
        written += _write_text(store, node.value, reader.construct(rules.construct).decode("utf-8").splitlines(True))
    # Text through the bulk loader, in pieces (each bulk load call costs ~0.1 s of file
    # ingestion on disk, whatever its size, and holds memory in proportion to it); the lines
    # are made as they are written (a program of 1M instances has ~300k of them here).
    written += _write_text(store, node.value, itertools.chain(
        order.triples(graph), order.feature_triples(), instance_counts(reader, graph),
        [f"<{layer}> {_sga('layerOf')} <{graph}> .\n", f"<{layer}> {_sga('layerVersion')} {_integer(LAYER_VERSION)} .\n"]))
    del order
    if store.capabilities.blank_node_writes:
        # The quads that hold blank nodes go as quads (a blank node has no name SPARQL or a
        # second text could give it), streamed: in one transaction when few, else in bulk calls
        written += store.add_quads(lists.index_quads(node))
        del lists  # the cells: the largest part of this function's memory
        written += store.add_quads(ox.Quad(s, p, o, node) for s, p, o in reader.select(rules.blank_values))
    else:  # a remote store: blank nodes cannot be named across requests, so the store copies them
        before = store.count(node.value)
        store.update(_blank_updates(rules, target(graph), node.value))
        written += store.count(node.value) - before
    return DerivedLayer(layer, (mapped or 0) + written, steps)


def instance_counts(reader: _Reader, graph: str) -> Iterator[str]:
    """How many instances (IRIs, not the blank nodes of typed values) the program's graph types
    with each class, as it types them (no superclasses): one ``sga:ClassCount`` per class, with
    ``sga:countedIn``, ``sga:countedClass`` and ``sga:instanceCount``, in the order of the classes'
    IRIs (so a re-load of the same file writes the same lines)."""
    rows = reader.select("SELECT ?c (COUNT(?i) AS ?n) WHERE { ?i a ?c FILTER(isIRI(?i)) } GROUP BY ?c ORDER BY ?c")
    kind, program, counted, count = (_sga(n) for n in ("ClassCount", "countedIn", "countedClass", "instanceCount"))
    for index, (cls, n) in enumerate((r for r in rows if isinstance(r[0], ox.NamedNode)), start=1):
        me = f"<{class_count_iri(graph, index)}>"
        yield f"{me} {RDF_TYPE} {kind} .\n"
        yield f"{me} {program} <{graph}> .\n"
        yield f"{me} {counted} {cls} .\n"
        yield f"{me} {count} {_integer(int(n.value))} .\n"


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


def _blank_updates(rules: DeriveRules, source: str, layer: str) -> str:
    """The blank-node part of the layer as SPARQL Update, for a remote store: generic values that
    are lists or typed values, and ``sga:index`` on the cells of the process lists."""
    where = rules.blank_values.split("WHERE", 1)[1].strip()[1:-1]
    index = ox.NamedNode(ANALYSIS_NS + "index")
    return (f"INSERT {{ GRAPH <{layer}> {{ ?s ?q ?o }} }} WHERE {{ GRAPH <{source}> {{ {where} }} }} ;\n"
            f"INSERT {{ GRAPH <{layer}> {{ ?cell {index} ?n }} }} WHERE {{ {{ SELECT ?cell (COUNT(DISTINCT ?mid) AS ?n) "
            f"WHERE {{ GRAPH <{source}> {{ VALUES ?p {{ {_values(rules.list_properties)} }} ?s ?p ?head . "
            f"?head <{RDF_NS}rest>* ?mid . ?mid <{RDF_NS}rest>* ?cell . ?cell <{RDF_NS}first> ?x }} }} "
            f"GROUP BY ?cell }} }}")


def superclasses(class_iri: str, rules: DeriveRules | None = None) -> tuple[str, ...]:
    """The superclasses the derived layer gives an instance of ``class_iri`` (empty for resources)."""
    return (rules or iso14649_rules()).superclasses.get(class_iri, ())
