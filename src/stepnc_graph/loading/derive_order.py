"""The walks of the derived layer (:mod:`.derive`) over ``rdf:List`` chains: list positions
(:class:`Lists`) and the program's execution order (:class:`ExecutionOrder`), read through a few
SELECTs (:class:`Reader`)."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.core.naming import (
    ANALYSIS_NS,
    P21_NS,
    STEPNC_NS,
    execution_step_iri,
    instance_id,
)
from stepnc_graph.loading.derive_rules import RDF_NS, RDF_TYPE, DeriveRules, Term, integer_literal, sga
from stepnc_graph.mapping.ntriples import string

if TYPE_CHECKING:
    from stepnc_graph.store import Store



#: Program structures whose members run in a given order (a LIST) or in no
#: stated order (a SET: flattened in #id order), and single-valued branches.
_ORDERED = {"workplan": "its_elements"}
_UNORDERED = {"parallel": "branches", "non_sequential": "its_elements", "selective": "its_elements"}
_BRANCHES = {"if_statement": ("true_branch", "false_branch"), "while_statement": ("body",)}
#: the lists the execution order walks (:meth:`ExecutionOrder.children`, ``feature_triples``):
#: when the layer's list positions came with the program's text, only these cells are read
ORDER_LISTS = (*(f"{STEPNC_NS}{e}.{a}" for e, a in _ORDERED.items()), f"{STEPNC_NS}turning_workingstep.its_features")




class Reader:
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


def values_clause(iris: Iterable[str]) -> str:
    return " ".join(f"<{i}>" for i in iris)


@dataclass
class Lists:
    """The cells of the process lists of a graph: first/rest of each, and each list's members."""

    first: dict[Term, Term]
    rest: dict[Term, Term]

    @classmethod
    def read(cls, reader: Reader, properties: tuple[str, ...]) -> "Lists":
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
    def _select(cls, reader: Reader, properties: tuple[str, ...], path: str) -> "Lists":
        rows = reader.select(
            f"SELECT ?cell ?first ?rest WHERE {{ VALUES ?p {{ {values_clause(properties)} }} "
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

    def __init__(self, reader: Reader, rules: DeriveRules, lists: Lists) -> None:
        self.rules = rules
        self.lists = lists
        self.kind: dict[ox.NamedNode, str] = {}
        self.ids: dict[ox.NamedNode, int] = {}
        for x, c, i in reader.select(
                f"SELECT ?x ?c ?id WHERE {{ VALUES ?c {{ {values_clause(STEPNC_NS + n for n in rules.executables)} }} "
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
        for s, p, o in reader.select(f"SELECT ?s ?p ?o WHERE {{ VALUES ?p {{ {values_clause(names)} }} ?s ?p ?o }}"):
            self.edges[(s, p.value[len(STEPNC_NS):])].append(o)
        self.tool: dict[Term, Term] = {}  # workingstep -> the tool of its operation
        self.op: dict[Term, Term] = {}  # workingstep -> its operation
        for ws, op, tool in reader.select(
                f"SELECT ?ws ?op ?tool WHERE {{ VALUES ?p {{ {values_clause(rules.operation_properties)} }} "
                f"?ws ?p ?op OPTIONAL {{ VALUES ?q {{ {values_clause(rules.tool_properties)} }} ?op ?q ?tool }} }}"):
            self.op[ws] = op
            if tool is not None:
                self.tool[ws] = tool
        #: workingstep -> the #id and the classes (as typed in the program's graph) of its operation
        self.operation: dict[Term, tuple[int, list[Term]]] = {}
        for ws, cls, ident in reader.select(
                f"SELECT ?ws ?c ?id WHERE {{ VALUES ?p {{ {values_clause(rules.operation_properties)} }} "
                f"?ws ?p ?op . ?op a ?c ; <{P21_NS}id> ?id }}"):
            self.operation.setdefault(ws, (int(ident.value), []))[1].append(cls)
        self.reader = reader
        self.names = _names(reader, rules)
        self.bodies = _classes_of(reader, rules, "tool_body", _tool_bodies(reader, rules))
        self.features = _classes_of(reader, rules, "manufacturing_feature")
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
        cls = sga("ExecutionStep")
        order, executes, workplan, setup, nxt, tool, before = (
            sga(n) for n in ("order", "executes", "workplan", "setup", "next", "tool", "toolBefore"))
        program, ws_id, op_id, op_class, op_type = (
            sga(n) for n in ("program", "workingstepId", "operationId", "operationClass", "operationType"))
        graph_node = f"<{graph}>"
        tool_ids = self.instance_ids(graph, set(self.tool.values()))
        spindle: Term | None = None  # the tool of the last step that had one
        for i, s in enumerate(self.steps):
            me = iri[i]
            yield f"{me} {RDF_TYPE} {cls} .\n"
            yield f"{me} {order} {integer_literal(s.order)} .\n"
            yield f"{me} {executes} {s.workingstep} .\n"
            yield f"{me} {program} {graph_node} .\n"
            yield f"{me} {ws_id} {integer_literal(self.ids[s.workingstep])} .\n"
            if (operation := self.operation.get(s.workingstep)) is not None:
                yield f"{me} {op_id} {integer_literal(operation[0])} .\n"
                yield from (f"{me} {op_class} {c} .\n" for c in operation[1])
                yield from type_names(me, op_type, operation[1])
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
            yield from self._shown(me, s, tool_ids)

    def _shown(self, me: str, step: Step, ids: dict[Term, int]) -> Iterator[str]:
        """The operation, the names, the tool's #id and its body's class on the step ``me``: what a
        row per step shows of the things the step names (see :mod:`.derive`)."""
        names = self.names
        operation = self.op.get(step.workingstep)
        if isinstance(operation, ox.NamedNode):
            yield f"{me} {sga('operation')} {operation} .\n"
        named = (("workingstepName", step.workingstep), ("operationName", operation),
                 ("workplanName", step.workplan), ("setupName", step.setup))
        for prop, thing in named:
            if thing is not None and (name := names.get(thing)) is not None:
                yield f"{me} {sga(prop)} {name} .\n"
        used = self.tool.get(step.workingstep)
        if isinstance(used, ox.NamedNode):
            if (name := names.get(used)) is not None:
                yield f"{me} {sga('toolName')} {name} .\n"
            if (number := ids.get(used)) is not None:
                yield f"{me} {sga('toolId')} {integer_literal(number)} .\n"
            yield from (f"{me} {sga('toolBodyClass')} {c} .\n" for c in self.bodies.get(used, ()))
            yield from type_names(me, sga("toolBodyType"), self.bodies.get(used, ()))

    def instance_ids(self, graph: str, things: Iterable[Term]) -> dict[Term, int]:
        """The #id of each of ``things``: read from its IRI where the loader minted it for ``graph``
        (:func:`~stepnc_graph.core.naming.instance_id`: no look-up), else its ``p21:id``."""
        ids: dict[Term, int] = {}
        other: list[Term] = []
        for thing in things:
            number = instance_id(graph, thing.value) if isinstance(thing, ox.NamedNode) else None
            if number is None:
                other.append(thing)
            else:
                ids[thing] = number
        if other:
            for thing, number in self.reader.select(
                    f"SELECT ?x ?id WHERE {{ VALUES ?x {{ {' '.join(str(t) for t in other)} }} ?x <{P21_NS}id> ?id }}"):
                ids[thing] = int(number.value)
        return ids

    def feature_facts(self, graph: str) -> Iterator[str]:
        """On each manufacturing feature of the program: its #id, its classes as the program's graph
        types it and their local names, and the program (``sga:featureId``, ``sga:featureClass``,
        ``sga:typeName``, ``sga:featureProgram``), in #id order."""
        ident, cls, name, program = sga("featureId"), sga("featureClass"), sga("typeName"), sga("featureProgram")
        ids = self.instance_ids(graph, self.features)
        for feature, number in sorted(ids.items(), key=lambda kv: kv[1]):
            yield f"{feature} {ident} {integer_literal(number)} .\n"
            yield from (f"{feature} {cls} {c} .\n" for c in self.features[feature])
            yield from type_names(str(feature), name, self.features[feature])
            yield f"{feature} {program} <{graph}> .\n"

    def operation_facts(self, graph: str) -> Iterator[str]:
        """On each operation of the program: the local names of its classes as the program's graph
        types it (``sga:typeName``), in #id order."""
        name = sga("typeName")
        operations = _classes_of(self.reader, self.rules, "operation")
        for operation, _ in sorted(self.instance_ids(graph, operations).items(), key=lambda kv: kv[1]):
            yield from type_names(str(operation), name, operations[operation])

    def feature_triples(self) -> Iterator[str]:
        """``sga:feature`` from each workingstep to the features it machines, one line at a time."""
        feature = sga("feature")
        for node in sorted(self.kind, key=lambda n: self.ids[n]):
            single = self.one(node, "machining_workingstep.its_feature")
            many = self.one(node, "turning_workingstep.its_features")
            targets = ([single] if single is not None else []) + (self.lists.members(many) if many else [])
            for t in targets:
                if isinstance(t, ox.NamedNode):
                    yield f"{node} {feature} {t} .\n"


def type_names(subject: str, prop: str, classes: Iterable[Term]) -> Iterator[str]:
    """The N-Triples lines giving ``subject`` (N-Triples text) the local name of each of ``classes``
    as ``prop`` (see :func:`type_name`)."""
    for cls in classes:
        if isinstance(cls, ox.NamedNode):
            yield f"{subject} {prop} {type_name(cls)} .\n"


def type_name(cls: ox.NamedNode) -> str:
    """The local name of a class (what follows the first ``#`` of its IRI, as SPARQL's
    ``STRAFTER(STR(?class), "#")`` gives it) as an N-Triples string: the ``*_type`` column of a
    library row, written once at load instead of computed per row by every query. A class is an
    IRI; a term of another kind has no local name (``STR`` of a blank node is an error)."""
    return string(cls.value.partition("#")[2])


def _carrying(rules: DeriveRules, attribute: str) -> list[str]:
    """The properties whose generic value (``attr:<attribute>``) the layer writes: each entity's
    own ``attribute`` property, sorted."""
    return sorted(p for p, g in rules.generic.items() if g.endswith("#" + attribute))


def _names(reader: Reader, rules: DeriveRules) -> dict[Term, ox.Literal]:
    """The its_id of every instance that has one (workingsteps, workplans, operations, setups,
    tools, features, ...; the values ``attr:its_id`` has): what the steps' name facts copy."""
    names: dict[Term, ox.Literal] = {}
    its_id = _carrying(rules, "its_id")
    for thing, name in reader.select(
            f"SELECT ?x ?name WHERE {{ VALUES ?p {{ {values_clause(its_id)} }} ?x ?p ?name }}"):
        if isinstance(name, ox.Literal):
            names[thing] = name
    return names


def _tool_bodies(reader: Reader, rules: DeriveRules) -> dict[Term, list[Term]]:
    """Each tool -> its tool bodies (one scan of the its_tool_body attributes)."""
    properties = _carrying(rules, "its_tool_body")
    bodies: dict[Term, list[Term]] = defaultdict(list)
    for tool, body in reader.select(f"SELECT ?t ?b WHERE {{ VALUES ?q {{ {values_clause(properties)} }} ?t ?q ?b }}"):
        bodies[tool].append(body)
    return bodies


def _classes_of(reader: Reader, rules: DeriveRules, root: str,
                through: dict[Term, list[Term]] | None = None) -> dict[Term, list[Term]]:
    """Each instance of a class the derived layer closes over ``root`` (any edition) -> the classes
    the program's graph types it with, among those (its own entity, not the superclasses the layer
    adds), sorted; one scan per class, no look-up per instance. With ``through`` (thing -> its
    instances of ``root``): each thing -> the classes of its instances instead."""
    iri = STEPNC_NS + root
    classes = sorted(c for c, supers in rules.superclasses.items() if c == iri or iri in supers)
    found: dict[Term, list[Term]] = defaultdict(list)
    for thing, cls in reader.select(f"SELECT ?x ?c WHERE {{ VALUES ?c {{ {values_clause(classes)} }} ?x a ?c }}"):
        if isinstance(thing, ox.NamedNode):
            found[thing].append(cls)
    for members in found.values():
        members.sort(key=str)
    if through is None:
        return found
    return {thing: [c for m in members for c in found.get(m, ())] for thing, members in through.items()}


# -- writing -------------------------------------------------------------------
