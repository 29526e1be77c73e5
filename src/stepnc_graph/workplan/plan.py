"""The workplan of a loaded program as a networkx graph, its analyses, GraphML and an SVG picture.

Built from one file's graph and its derived layer (:mod:`stepnc_graph.loading.derive`):
project -> workplans (nested, ``element`` edges with their index) -> workingsteps, which are
linked in execution order (``next`` edges carry the order) and to their feature(s), operation,
tool and technology; setups group the workingsteps that run in them (``runs`` edges).

The analyses are computed here in Python from the execution steps, independently of the SPARQL
library (tests compare the two): execution order, tool changes, precedence (a finishing step
before a roughing step on the same feature), workingsteps per setup, tools shared across setups
and the critical (most used) tool.

The picture is written by our own small SVG writer (no plotting dependency; networkx's drawing
needs matplotlib and knows nothing of lanes): titled by the program's project, setups are lanes,
workingsteps boxes in execution order coloured by the body type of their tool (a legend names
each), in rows of a readable width, tool changes marked, rough -> finish pairs of a feature joined
by arcs (red and dashed when the finish comes first); a large plan is drawn as runs of steps with
one setup and one tool, in pages (:class:`PlanPicture`). PNG needs the ``png`` extra (cairosvg).
"""

from __future__ import annotations

import csv
import io
import json
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from html import escape
from pathlib import PurePath
from typing import TYPE_CHECKING, Any
from urllib.parse import unquote

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError, listed_by, option
from stepnc_graph.core.naming import STEPNC_NS, VOCABULARY_GRAPH, derived_graph_iri, instance_id, program_graphs
from stepnc_graph.querying.query import PREFIXES

if TYPE_CHECKING:
    import networkx as nx

    from stepnc_graph.store.contract import Store

PALETTE = ("#4e79a7", "#f28e2b", "#59a14f", "#b07aa1", "#76b7b2", "#edc948", "#ff9da7", "#9c755f", "#bab0ac",
           "#e15759")


def _ink(fill: str) -> str:
    """Text colour readable on ``fill``: dark on light colours (relative luminance above 0.5)."""
    r, g, b = (int(fill[i:i + 2], 16) / 255 for i in (1, 3, 5))
    return "#222" if 0.2126 * r + 0.7152 * g + 0.0722 * b > 0.5 else "#fff"


class PlanError(StepncGraphError, ValueError):
    """No such program in the store, or a store the plan cannot be read from."""


@dataclass(frozen=True)
class Thing:
    """A workingstep, feature, tool, setup, workplan, ...: its IRI, its_id and #id."""

    iri: str
    label: str
    ref: str
    cls: str = ""


@dataclass(frozen=True)
class Technology:
    """An operation's technology: #id, class and the numbers it states (``values``: attribute name
    and value, the shortest text of the number; its own attributes first, then those of the
    entities it names -- a turning technology's spindle speed --, each in Part 21 parameter order)."""

    iri: str
    ref: str
    cls: str
    values: tuple[tuple[str, str], ...] = ()

    def text(self, sep: str = " ") -> str:
        """``feedrate=0.25 speed=180 ...`` (the class when it states no number)."""
        return sep.join(f"{k}={v}" for k, v in self.values) or self.cls


#: the legend's names for steps whose tool has no body, and steps without a tool
NO_TOOL_BODY, NO_TOOL = "no tool body", "no tool"


@dataclass
class Step:
    """One step of the execution order."""

    order: int
    workingstep: Thing
    workplan: Thing | None
    setup: Thing | None
    tool: Thing | None
    operation: Thing | None
    features: list[Thing] = field(default_factory=list)
    kind: str = ""  # "rough", "finish" or ""
    #: the first step of a root of the execution order (a project's main workplan): the tool it
    #: takes is loaded, not changed (the derived layer's rule, see stepnc_graph.loading.derive)
    starts_root: bool = False
    technology: Technology | None = None
    #: the class of the tool's body as the program's graph types it (``general_turning_tool``,
    #: ``twist_drill``, ...), :data:`NO_TOOL_BODY` or :data:`NO_TOOL`
    tool_body: str = NO_TOOL


@dataclass(frozen=True)
class ToolChange:
    order: int
    workingstep: Thing
    before: Thing
    after: Thing


@dataclass(frozen=True)
class Precedence:
    """A finishing step that runs before a roughing step on the same feature."""

    feature: Thing
    finish: int
    rough: int


def _rows(store: Store, graph: str, query: str) -> list[list[str]]:
    """The rows of ``query`` over one program (its graph, its derived layer and the vocabulary; ``GRAPH
    ?g`` for the program's own triples): each value the term's text ("" when unbound), in the order
    SELECTed. Read as SPARQL CSV, which Oxigraph writes and Python's csv module reads without a
    Python object per term (a third of the time for the 36,000 things of a 100k-instance program)."""
    result = store.query(query, prefixes=PREFIXES,
                         default_graph=[ox.NamedNode(g) for g in (graph, derived_graph_iri(graph), VOCABULARY_GRAPH)],
                         named_graphs=[ox.NamedNode(graph)])
    text = (result.serialize(format=ox.QueryResultsFormat.CSV) or b"").decode("utf-8")
    return list(csv.reader(io.StringIO(text, newline="")))[1:]


# The queries read the derived layer's execution steps and what they name, each property in one scan
# joined by hashing (docs/querying.md, "Writing fast queries"); list chains are followed in Python.
# A program of 100k instances has 9,000 steps and 36,000 things to show: a look-up per thing, or a
# property path per list, took most of the time.
_STEPS = """
SELECT ?order ?ws ?wp ?setup ?tool WHERE {
  { SELECT ?step ?order WHERE { ?step sga:order ?order } }
  { SELECT ?step ?ws WHERE { ?step sga:executes ?ws } }
  OPTIONAL { { SELECT ?step ?wp WHERE { ?step sga:workplan ?wp } } }
  OPTIONAL { { SELECT ?step ?setup WHERE { ?step sga:setup ?setup } } }
  OPTIONAL { { SELECT ?step ?tool WHERE { ?step sga:tool ?tool } } }
}"""
#: the last step of each root of the execution order (sga:next joins the steps of one root only)
_LAST = "SELECT ?order WHERE { ?step sga:order ?order MINUS { ?step sga:next ?next } }"
_KINDS = """
SELECT ?op ?kind WHERE {
  { ?op a sga:RoughingOperation BIND("rough" AS ?kind) } UNION { ?op a sga:FinishingOperation BIND("finish" AS ?kind) }
}"""
#: the workingsteps' features and operations
_STEP_EDGES = """
SELECT ?s ?p ?o WHERE { { ?s sga:feature ?o BIND("feature" AS ?p) } UNION { ?s attr:its_operation ?o BIND("operation" AS ?p) } }"""
#: the operations' technologies, the projects' main workplans (for the graph)
_MORE_EDGES = """
SELECT ?s ?p ?o WHERE {
  { SELECT DISTINCT ?s ?p ?o WHERE {
    { SELECT ?s WHERE { ?x attr:its_operation ?s } } { SELECT ?s ?o WHERE { ?s attr:its_technology ?o } }
    BIND("technology" AS ?p) } }
  UNION { ?s stepnc:project.main_workplan ?o BIND("main_workplan" AS ?p) }
}"""
#: the members of program structures but workplans (``?i``: the branch of an if statement, else 0)
_MEMBERS = """
SELECT ?s ?o ?i WHERE {
  { ?s stepnc:parallel.branches|stepnc:non_sequential.its_elements|stepnc:selective.its_elements ?o BIND(0 AS ?i) }
  UNION { ?s stepnc:if_statement.true_branch ?o BIND(1 AS ?i) }
  UNION { ?s stepnc:if_statement.false_branch ?o BIND(2 AS ?i) }
  UNION { ?s stepnc:while_statement.body ?o BIND(1 AS ?i) }
}"""
#: the workplans' element lists: their heads, and every indexed list cell (sga:index: the derived
#: layer's positions, on the cells of the process lists) with its member and the next cell
_HEADS = "SELECT ?s ?head WHERE { ?s stepnc:workplan.its_elements ?head }"
_CELLS = """
SELECT ?cell ?i ?o ?rest WHERE {
  { SELECT ?cell ?i WHERE { ?cell sga:index ?i } }
  { SELECT ?cell ?o WHERE { ?cell rdf:first ?o } }
  { SELECT ?cell ?rest WHERE { ?cell rdf:rest ?rest } }
}"""
#: what the plan shows of a thing (its_id, #id and class as the program's graph types it; a row per
#: class), for the things ``NAMED`` names
_THINGS = """
SELECT ?x ?label ?n ?cls WHERE {
  { SELECT DISTINCT ?x WHERE { NAMED } }
  { SELECT ?x ?n WHERE { GRAPH ?g { ?x p21:id ?n } } }
  OPTIONAL { { SELECT ?x ?cls WHERE { GRAPH ?g { ?x a ?cls } } } }
  OPTIONAL { { SELECT ?x ?label WHERE { ?x attr:its_id ?label } } }
}"""
_STEP_THINGS = "?s sga:executes|sga:workplan|sga:setup|sga:tool|sga:feature|attr:its_operation ?x"
#: the program's projects (its_id, #id): the plan's title
_PROJECTS = "SELECT ?n ?label WHERE { GRAPH ?g { ?p stepnc:project.its_id ?label ; p21:id ?n } }"
#: the file the program was read from (dcterms:source, on the program's graph node)
_SOURCE = "SELECT ?src WHERE { GRAPH ?g { ?g <http://purl.org/dc/terms/source> ?src } } LIMIT 1"
#: the vocabulary's classes under ``ROOT``, an older edition's names of them too (equivalent classes;
#: ``(rdfs:subClassOf|owl:equivalentClass)*`` joined with the program took 20 CPU-s at 100k instances)
_CLASSES = """
SELECT ?cls WHERE { { ?cls rdfs:subClassOf* ROOT } UNION { ?cls owl:equivalentClass ?c . ?c rdfs:subClassOf* ROOT } }"""
#: every tool's body (``body``) and the class the program's graph gives each tool body (``class``, one
#: of ``CLASSES``), a scan each, joined in Python (0.05 CPU-s at 100k instances, against 0.26 looking
#: up the bodies of the steps' tools; Virtuoso 7.2 drops rows of a join of the two as sub-SELECTs)
_BODIES = """
SELECT ?s ?p ?o WHERE {
  { ?s attr:its_tool_body ?o BIND("body" AS ?p) }
  UNION { VALUES ?cls { CLASSES } GRAPH ?g { ?s a ?cls } BIND(STR(?cls) AS ?o) BIND("class" AS ?p) }
}"""
#: the vocabulary's attributes of the classes under ``ROOTS`` (their ranges, Part 21 positions)
_ATTRIBUTES = """
SELECT ?root ?p ?range ?pos WHERE {
  VALUES ?root { ROOTS } ?d rdfs:subClassOf* ?root . ?p rdfs:domain ?d ; rdfs:range ?range OPTIONAL { ?p p21:position ?pos }
}"""
#: the technologies: which operation has which (``technology``), their classes (``class``, one of
#: ``CLASSES``), the
#: values of the attributes ``NUMBERS`` names and the entities ``REFS`` names: each property one
#: scan of the program (0.3 CPU-s at 100k instances; one query looking up every triple of each
#: technology and of what it names, filtered for numbers, took 30)
_TECHNOLOGIES = """
SELECT ?s ?p ?o WHERE {
  { ?s attr:its_technology ?o BIND("technology" AS ?p) }
  UNION { VALUES ?cls { CLASSES } GRAPH ?g { ?s a ?cls } BIND(STR(?cls) AS ?o) BIND("class" AS ?p) }
  UNION { VALUES ?p { NUMBERS } GRAPH ?g { ?s ?p ?o } }
  UNION { VALUES ?p { REFS } GRAPH ?g { ?s ?p ?o } }
}"""
#: the XML Schema datatypes of numbers
_NUMERIC = {f"http://www.w3.org/2001/XMLSchema#{t}" for t in ("double", "float", "decimal", "integer", "int", "long")}
_MORE_THINGS = "{ ?s attr:its_technology ?x } UNION { ?x stepnc:project.main_workplan ?w }"
#: the same for a few things by IRI
_THING = """
SELECT ?x ?label ?n ?cls WHERE { GRAPH ?g { ?x p21:id ?n OPTIONAL { ?x a ?cls } } OPTIONAL { ?x attr:its_id ?label } }"""


class Plan:
    """The plan of one loaded program: the execution ``steps`` and ``graph`` (a networkx MultiDiGraph;
    ``build_plan(..., network=False)`` leaves it out: the analyses, the summary text and the picture
    need the steps only), the program's ``projects`` (their its_id, in #id order) and the file it was
    read from (``source``, as its load recorded it; None if unknown)."""

    def __init__(self, program: str, steps: list[Step], graph: nx.MultiDiGraph | None = None, *,
                 projects: list[str] | None = None, source: str | None = None) -> None:
        self.program = program
        self.steps = steps
        self._graph = graph
        self.projects = projects or []
        self.source = source

    @property
    def title(self) -> str:
        """What the plan is called: its project's its_id (a program of several projects: the first
        three, and how many more). A program without a project (ISO 14649 requires one, but a
        fragment loads too) falls back to the name of the file its graph was loaded from, else to
        the last segment of the graph's IRI."""
        if self.projects:
            more = len(self.projects) - 3
            return ", ".join(self.projects[:3]) + (f" and {more} more projects" if more > 0 else "")
        return self.file_name

    @property
    def file_name(self) -> str:
        """The name of the file the program was loaded from, else the last segment of its graph IRI."""
        if self.source:
            return PurePath(self.source).name or self.source
        return unquote(self.program.rstrip("/#").rsplit("/", 1)[-1]) or self.program

    @property
    def graph(self) -> nx.MultiDiGraph:
        if self._graph is None:
            raise PlanError("this plan was built without its graph: build_plan(store, graph, network=True)")
        return self._graph

    # -- analyses ------------------------------------------------------------------------------

    def execution_order(self) -> list[Step]:
        return list(self.steps)

    def tool_changes(self) -> list[ToolChange]:
        """Steps whose tool differs from the one in the spindle (the last tool used before, in the same
        root of the execution order: another project's first tool is a load, not a change)."""
        out = []
        spindle: Thing | None = None
        for s in self.steps:
            if s.starts_root:
                spindle = None
            if s.tool is None:
                continue
            if spindle is not None and s.tool.iri != spindle.iri:
                out.append(ToolChange(s.order, s.workingstep, spindle, s.tool))
            spindle = s.tool
        return out

    def precedence_violations(self) -> list[Precedence]:
        """Finishing before roughing on the same feature (each pair once)."""
        out = []
        for feature, finishes, roughs in self._by_feature():
            out += [Precedence(feature, f, r) for f in finishes for r in roughs if f < r]
        return sorted(out, key=lambda p: (p.finish, p.rough))

    def rough_finish_pairs(self) -> list[tuple[Thing, int, int]]:
        """(feature, roughing step order, finishing step order) for every pair on a feature."""
        return sorted(((f, r, fin) for f, finishes, roughs in self._by_feature() for r in roughs for fin in finishes),
                      key=lambda x: (x[1], x[2]))

    def _by_feature(self) -> list[tuple[Thing, list[int], list[int]]]:
        finishes: dict[str, list[int]] = defaultdict(list)
        roughs: dict[str, list[int]] = defaultdict(list)
        things: dict[str, Thing] = {}
        for s in self.steps:
            for f in s.features:
                things[f.iri] = f
                if s.kind == "finish":
                    finishes[f.iri].append(s.order)
                elif s.kind == "rough":
                    roughs[f.iri].append(s.order)
        return [(things[k], finishes[k], roughs[k]) for k in sorted(things, key=lambda k: things[k].ref)]

    def workingsteps_per_setup(self) -> dict[str, list[Step]]:
        out: dict[str, list[Step]] = {}
        for s in self.steps:
            out.setdefault(s.setup.label if s.setup else "", []).append(s)
        return out

    def shared_tools(self) -> dict[str, list[str]]:
        """Tool ref -> the setups (in order of first use) of the tools more than one setup uses."""
        setups: dict[str, list[str]] = defaultdict(list)
        for s in self.steps:
            if s.tool is not None and s.setup is not None and s.setup.label not in setups[s.tool.ref]:
                setups[s.tool.ref].append(s.setup.label)
        return {t: ss for t, ss in setups.items() if len(ss) > 1}

    def tool_usage(self) -> list[tuple[Thing, int]]:
        """Tools by number of steps, most used first (ties: first used first)."""
        counts = Counter(s.tool.iri for s in self.steps if s.tool)
        first: dict[str, Step] = {}
        for s in self.steps:
            if s.tool and s.tool.iri not in first:
                first[s.tool.iri] = s
        return sorted(((first[t].tool, n) for t, n in counts.items()),  # type: ignore[misc]
                      key=lambda tn: (-tn[1], first[tn[0].iri].order))

    def critical_tool(self) -> tuple[Thing, int] | None:
        usage = self.tool_usage()
        return usage[0] if usage else None

    # -- outputs ---------------------------------------------------------------------------------

    def summary(self) -> dict[str, Any]:
        critical = self.critical_tool()
        return {
            "program": self.program,
            "title": self.title,
            "projects": self.projects,
            "workingsteps": len(self.steps),
            "setups": {k: [s.order for s in v] for k, v in self.workingsteps_per_setup().items()},
            "tool_changes": [{"order": c.order, "workingstep": c.workingstep.label, "ref": c.workingstep.ref,
                              "from": c.before.label, "from_ref": c.before.ref, "to": c.after.label,
                              "to_ref": c.after.ref} for c in self.tool_changes()],
            "precedence_violations": [{"feature": p.feature.label, "ref": p.feature.ref, "finish": p.finish,
                                       "rough": p.rough} for p in self.precedence_violations()],
            "shared_tools": self.shared_tools(),
            "critical_tool": {"tool": critical[0].label, "ref": critical[0].ref, "workingsteps": critical[1]}
            if critical else None,
            "steps": [{"order": s.order, "workingstep": s.workingstep.label, "ref": s.workingstep.ref,
                       "setup": s.setup.label if s.setup else None, "tool": s.tool.label if s.tool else None,
                       "tool_ref": s.tool.ref if s.tool else None, "tool_body": s.tool_body, "kind": s.kind,
                       "operation": s.operation.cls if s.operation else None, "features": [f.ref for f in s.features],
                       "technology": dict(s.technology.values) if s.technology else None} for s in self.steps],
            "graph": {"nodes": self.graph.number_of_nodes(), "edges": self.graph.number_of_edges()},
        }

    def to_json(self) -> str:
        return json.dumps(self.summary(), indent=2)

    def graphml(self) -> str:
        """GraphML for other tools (yEd, Gephi, Cytoscape): every attribute a string or number."""
        import networkx as nx

        return "\n".join(nx.generate_graphml(self.graph, named_key_ids=True)) + "\n"

    def svg(self, page: int = 1) -> str:
        """The picture (page ``page`` of :meth:`pages`): see :class:`PlanPicture`."""
        return PlanPicture(self).render(page)

    def pages(self) -> int:
        """How many pages the picture has (one unless the plan is summarised in blocks)."""
        return PlanPicture(self).pages()


# -- building --------------------------------------------------------------------------------------


def _thing(info: dict[str, Thing], iri: str | None) -> Thing | None:
    if not iri:
        return None
    return info.get(iri) or Thing(iri, "", "", "")


def _things(store: Store, graph: str, named: str, info: dict[str, Thing]) -> None:
    """Add the Things ``named`` names (a SPARQL pattern binding ``?x``) to ``info``."""
    for x, label, n, cls in _rows(store, graph, _THINGS.replace("NAMED", named)):
        info[x] = Thing(x, label, f"#{n}" if n else "", cls.rsplit("#", 1)[-1])


def _elements(store: Store, graph: str) -> list[tuple[str, str, int]]:
    """(structure, member, index) of every program structure: a workplan's elements in list order
    (index = place in the list), the members of the others (index: 1/2 for an if statement's
    branches, 1 for a loop's body, 0 for the sets of parallel, non-sequential and selective)."""
    cells = {cell: (int(i), o, rest) for cell, i, o, rest in _rows(store, graph, _CELLS)}
    out: list[tuple[str, str, int]] = []
    for s, head in _rows(store, graph, _HEADS):
        cell, seen = head, set()
        while cell in cells and cell not in seen:
            seen.add(cell)
            i, o, cell = cells[cell]
            out.append((s, o, i))
    out += [(s, o, int(i)) for s, o, i in _rows(store, graph, _MEMBERS)]
    return out


def _attributes(store: Store, graph: str, roots: set[str]) -> tuple[dict[str, tuple[str, int]], dict[str, str]]:
    """The attributes the vocabulary declares on the classes ``roots`` and their subclasses: those
    whose values are numbers (IRI -> the root, Part 21 position), and those that name entities
    (IRI -> the class they name)."""
    numbers: dict[str, tuple[str, int]] = {}
    refs: dict[str, str] = {}
    for root, p, range_, pos in _rows(store, graph, _ATTRIBUTES.replace("ROOTS", " ".join(f"<{r}>" for r in roots))):
        if range_ in _NUMERIC:
            numbers[p] = (root, int(pos or 0))
        elif not range_.startswith("http://www.w3.org/"):
            refs[p] = range_
    return numbers, refs


def _technologies(store: Store, graph: str) -> dict[str, Technology]:
    """Operation IRI -> its technology, with the numbers the technology states: its own attributes'
    and, after them, those of the entities it names (a turning technology's spindle speed), each in
    Part 21 parameter order. Which attributes hold numbers the vocabulary says, for any class of
    technology."""
    own, refs = _attributes(store, graph, {STEPNC_NS + "technology"})
    nested, _ = _attributes(store, graph, set(refs.values())) if refs else ({}, {})
    kept = {p for p, range_ in refs.items() if any(root == range_ for root, _ in nested.values())}
    numbers = {p: (0, pos) for p, (_, pos) in own.items()} | {p: (1, pos) for p, (_, pos) in nested.items()}
    query = (_TECHNOLOGIES.replace("NUMBERS", " ".join(f"<{p}>" for p in numbers) or "<urn:none>")
             .replace("REFS", " ".join(f"<{p}>" for p in sorted(kept)) or "<urn:none>")
             .replace("CLASSES", _classes(store, graph, "technology")))
    uses: dict[str, str] = {}
    classes: dict[str, str] = {}
    states: dict[str, list[tuple[tuple[int, int, str], str]]] = defaultdict(list)
    links: dict[str, list[str]] = defaultdict(list)
    for s, p, o in _rows(store, graph, query):
        if p == "technology":
            uses[s] = o
        elif p == "class":
            classes[s] = o.rsplit("#", 1)[-1]
        elif p in numbers:
            states[s].append((numbers[p] + (p,), _number(o)))
        else:
            links[s].append(o)
    techs: dict[str, Technology] = {}
    for tech in set(uses.values()):
        values = states[tech] + [v for x in links[tech] for v in states[x]]
        n = instance_id(graph, tech)
        techs[tech] = Technology(tech, f"#{n}" if n is not None else "", classes.get(tech, ""),
                                 tuple((key[2].rsplit("#", 1)[-1].rsplit(".", 1)[-1], v) for key, v in sorted(values)))
    return {op: techs[t] for op, t in uses.items()}


def _classes(store: Store, graph: str, root: str) -> str:
    """The vocabulary's classes under the entity ``root`` (and their older editions' names), as a
    SPARQL ``VALUES`` list."""
    found = _rows(store, graph, _CLASSES.replace("ROOT", f"<{STEPNC_NS}{root}>"))
    return " ".join(sorted({f"<{cls}>" for (cls,) in found})) or "<urn:none>"


def _number(text: str) -> str:
    """A number as the shortest text that reads back as it (``180``, ``0.25``): stores write a double's
    canonical form differently (Oxigraph ``180``, Virtuoso ``180.0``)."""
    try:
        value = float(text)
    except ValueError:
        return text
    if value.is_integer() and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def _tool_bodies(store: Store, graph: str) -> dict[str, str]:
    """Tool IRI -> the class of its body (a body of several classes: them all, joined by ``&``)."""
    bodies: dict[str, str] = {}
    classes: dict[str, set[str]] = defaultdict(set)
    for s, p, o in _rows(store, graph, _BODIES.replace("CLASSES", _classes(store, graph, "tool_body"))):
        if p == "body":
            bodies[s] = o
        else:
            classes[s].add(o.rsplit("#", 1)[-1])
    return {tool: " & ".join(sorted(classes[body])) for tool, body in bodies.items() if classes.get(body)}


def _steps(store: Store, graph: str, info: dict[str, Thing], features: dict[str, list[str]],
           operations: dict[str, str]) -> list[Step]:
    """The execution steps in order, with the things they name, whether they rough or finish and
    their tool's body type (:func:`_add_technologies` adds the technologies)."""
    kinds: dict[str, str] = {}
    for iri, kind in _rows(store, graph, _KINDS):
        if kinds.get(iri) != "rough":  # an operation that is both (none in ISO 14649) counts as roughing
            kinds[iri] = kind
    last = {int(order) for (order,) in _rows(store, graph, _LAST)}
    bodies = _tool_bodies(store, graph)
    steps: list[Step] = []
    for order, ws, wp, setup, tool in sorted(_rows(store, graph, _STEPS), key=lambda r: int(r[0])):
        op = operations.get(ws)
        steps.append(Step(int(order), info.get(ws) or Thing(ws, "", "", ""), _thing(info, wp), _thing(info, setup),
                          _thing(info, tool), _thing(info, op),
                          [f for f in (_thing(info, x) for x in sorted(features.get(ws, ()))) if f is not None],
                          kinds.get(op, "") if op else "", starts_root=not steps or steps[-1].order in last,
                          tool_body=bodies.get(tool, NO_TOOL_BODY) if tool else NO_TOOL))
    return steps


def _projects(store: Store, graph: str) -> list[str]:
    """The its_id of the program's projects in #id order, each name once."""
    names = [label for _, label in sorted(_rows(store, graph, _PROJECTS), key=lambda r: int(r[0]))]
    return list(dict.fromkeys(names))


def _add_technologies(store: Store, graph: str, steps: list[Step]) -> None:
    """Each step's :attr:`Step.technology`: its operation's."""
    technologies = _technologies(store, graph)
    for s in steps:
        if s.operation is not None:
            s.technology = technologies.get(s.operation.iri)


def build_plan(store: Store, graph: str | None = None, *, network: bool = True) -> Plan:
    """The plan of the program in ``graph`` (or the store's only program); without ``network``, the
    steps only (no :attr:`Plan.graph`: what `stepnc-graph plan` needs for its summary and picture),
    and their technologies (:attr:`Step.technology`) only when the picture shows them, a box per
    workingstep (at most :attr:`PlanPicture.DETAIL` steps: reading them takes 0.3 CPU-s for the
    9,000 steps of a 100k-instance program, whose picture shows runs of steps)."""
    from stepnc_graph.graphs.vocabulary_graph import vocabulary_for_queries

    vocabulary_for_queries(store)
    programs = program_graphs(store)
    if graph is None:
        if len(programs) != 1:
            raise PlanError(f"the store holds {len(programs)} programs; choose one with {option('graph')} "
                            f"({listed_by()})")
        graph = programs[0]
    if graph not in programs:
        raise PlanError(f"no loaded file with graph {graph}; `stepnc-graph info` lists them")
    info: dict[str, Thing] = {}
    _things(store, graph, _STEP_THINGS, info)
    edges = sorted({(s, p, o) for s, p, o in _rows(store, graph, _STEP_EDGES)})
    features: dict[str, list[str]] = defaultdict(list)
    operations: dict[str, str] = {}
    for s, p, o in edges:
        if p == "feature":
            features[s].append(o)
        else:
            operations[s] = o
    steps = _steps(store, graph, info, features, operations)
    projects, source = _projects(store, graph), next((src for (src,) in _rows(store, graph, _SOURCE)), None)
    if network or len(steps) <= PlanPicture.DETAIL:
        _add_technologies(store, graph, steps)
    if not network:
        return Plan(graph, steps, projects=projects, source=source)
    _things(store, graph, _MORE_THINGS, info)
    edges += sorted({(s, p, o) for s, p, o in _rows(store, graph, _MORE_EDGES)}, key=lambda e: (e[1], e))
    elements = _elements(store, graph)
    others = sorted({x for s, o, _ in elements for x in (s, o)
                     if x not in info and x.startswith(("http:", "https:")) and ">" not in x})
    if others:
        values = " ".join(f"<{x}>" for x in others)
        for x, label, n, cls in _rows(store, graph, _THING.replace("WHERE {", f"WHERE {{ VALUES ?x {{ {values} }}", 1)):
            info[x] = Thing(x, label, f"#{n}" if n else "", cls.rsplit("#", 1)[-1])
    return Plan(graph, steps, _network(graph, steps, info, edges, elements), projects=projects, source=source)


def _network(program: str, steps: list[Step], info: dict[str, Thing], edges: list[tuple[str, str, str]],
             elements: list[tuple[str, str, int]]) -> nx.MultiDiGraph:
    """The plan as a networkx graph: project -> workplans -> workingsteps in order, with their features,
    operations, tools, technologies and setups."""
    import networkx as nx  # only here: importing it takes 0.2-0.5 s, which a summary or a picture need not pay

    g: nx.MultiDiGraph = nx.MultiDiGraph(program=program)

    def node(iri: str, kind: str) -> None:
        t = info.get(iri) or Thing(iri, "", "", "")
        g.add_node(iri, kind=kind, label=t.label, ref=t.ref, cls=t.cls)

    for st in steps:
        node(st.workingstep.iri, "workingstep")
        g.nodes[st.workingstep.iri].setdefault("order", st.order)
        if st.setup is not None:
            node(st.setup.iri, "setup")
            g.add_edge(st.setup.iri, st.workingstep.iri, key=f"runs{st.order}", kind="runs", order=st.order)
        if st.tool is not None:
            node(st.tool.iri, "tool")
    for a, b in zip(steps, steps[1:], strict=False):
        g.add_edge(a.workingstep.iri, b.workingstep.iri, key=f"next{a.order}", kind="next", order=a.order)
    kinds = {"feature": "feature", "operation": "operation", "technology": "technology", "main_workplan": "workplan"}
    for s, p, o in edges:  # operations before their technology
        if s in g or p == "main_workplan":
            if p == "main_workplan":
                node(s, "project")
            node(o, kinds[p])
            g.add_edge(s, o, key=p, kind=p)
    for s, o, i in elements:
        if s in info and o in info:
            if s not in g:
                node(s, "workplan")
            if o not in g:
                node(o, "workplan")
            g.add_edge(s, o, key=f"element{i}", kind="element", index=i)
    for st in steps:
        if st.operation is not None and st.tool is not None:
            g.add_edge(st.operation.iri, st.tool.iri, key="tool", kind="tool")
    return g


# -- the picture -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Block:
    """Consecutive steps with one setup and one tool: one box of a summarised picture."""

    steps: tuple[Step, ...]

    @property
    def first(self) -> Step:
        return self.steps[0]

    @property
    def last(self) -> Step:
        return self.steps[-1]


def blocks(steps: list[Step]) -> list[Block]:
    """The steps cut wherever the setup or the tool changes."""
    out: list[list[Step]] = []
    for s in steps:
        if out and _block_key(out[-1][-1]) == _block_key(s):
            out[-1].append(s)
        else:
            out.append([s])
    return [Block(tuple(b)) for b in out]


def _block_key(s: Step) -> tuple[str | None, str | None]:
    return (s.setup.iri if s.setup else None, s.tool.iri if s.tool else None)


class PlanPicture:
    """An SVG of the plan that stays readable at any size: at most :data:`ROW` boxes a row.

    Titled by the plan's :attr:`Plan.title` (``<text class="title">``: the project's its_id, or the
    file name of a program without a project). Boxes are coloured by the body type of their tool
    (the class of the tool's ``its_tool_body`` as the program types it: ``general_turning_tool``,
    ``grooving_tool``, ``twist_drill``, ...); the legend below has one entry per type shown, with
    the tools of that type (``<g class="legend-type" data-type=..>``), and names steps whose tool
    has no body (:data:`NO_TOOL_BODY`) or that have no tool (:data:`NO_TOOL`).

    Up to :data:`DETAIL` workingsteps, one box per workingstep in execution order, in rows of
    :data:`ROW`; each row has one lane per setup, named by it and the workplans its steps run in;
    each box says the workingstep (its whole label, wrapped), #id and kind, the operation's class,
    the feature(s), the technology's numbers (feedrate, spindle speed, ...) and the tool, and its
    tooltip all of it uncut; tool changes marked, rough -> finish pairs of a feature joined by arcs
    (red and dashed when the finish comes first). Every workingstep box is ``<g class="workingstep"
    data-order=.. data-ref=.. data-tool=.. data-tool-body=..>``, every tool change ``<g
    class="tool-change" data-order=..>``, every rough/finish arc ``<path class="rough-finish"
    data-feature=..>`` (``precedence`` added when the finish comes first), every lane ``<g
    class="lane" data-setup=..>``, so the picture can be checked (and styled) by machine.

    Larger plans are summarised: one box per block of consecutive steps with one setup and one tool
    (``<g class="block" data-first=.. data-last=.. data-steps=.. data-setup=.. data-tool=..
    data-tool-body=..>``, ``precedence`` in its class when a finishing step in it runs before a
    roughing step on the same feature), :data:`BLOCK_ROW` a row, :data:`PAGE_BLOCKS` a page; a tool
    change is marked before the block it starts (``<g class="tool-change">``).
    """

    BOX_W, BOX_H, GAP, LANE_H, LEFT, TOP = 170, 106, 14, 150, 150, 70
    #: characters a box's line holds in :data:`BOX_W`: the label's (bold, 11 px), the others' (10 px)
    BOX_BOLD, BOX_CHARS = 20, 23
    #: at most this many boxes a row, and the most steps shown one box each (beyond: blocks)
    ROW, DETAIL = 16, 48
    #: tool body types the legend names at most, and tools named per type (the boxes name theirs)
    LEGEND, LEGEND_TOOLS, LEGEND_CHARS = 24, 4, 180
    BLOCK_W, BLOCK_H, BLOCK_ROW, PAGE_BLOCKS = 170, 64, 8, 120
    #: the fills of boxes whose tool has no body, and of boxes without a tool
    NO_BODY_FILL, NO_TOOL_FILL = "#ffffff", "#dddddd"

    def __init__(self, plan: Plan) -> None:
        self.plan = plan
        lanes: dict[str, None] = {}
        types: dict[str, int] = {}
        for s in plan.steps:
            lanes.setdefault(s.setup.label if s.setup else "(no setup)")
            if s.tool_body not in (NO_TOOL, NO_TOOL_BODY):
                types.setdefault(s.tool_body, len(types))
        self.lanes = list(lanes)
        self.lane = {name: i for i, name in enumerate(self.lanes)}
        #: tool body type -> its place in :data:`PALETTE` (in order of first use)
        self.types = types
        n = len(plan.steps)
        #: boxes a row: rows as even as they can be (13 steps: one row, 20: two of 10)
        self.row = -(-n // -(-n // self.ROW)) if n else 1

    def _lane_workplans(self) -> dict[str, str]:
        """Setup lane -> the workplans its steps run in (their its_id), in order of first use."""
        out: dict[str, list[str]] = {}
        for s in self.plan.steps:
            names = out.setdefault(s.setup.label if s.setup else "(no setup)", [])
            if s.workplan is not None and s.workplan.label and s.workplan.label not in names:
                names.append(s.workplan.label)
        return {lane: ", ".join(names) for lane, names in out.items()}

    def colour(self, step: Step) -> str:
        """The fill of a step's box: its tool body type's."""
        return self.type_colour(step.tool_body)

    def type_colour(self, tool_body: str) -> str:
        if tool_body == NO_TOOL:
            return self.NO_TOOL_FILL
        if tool_body == NO_TOOL_BODY:
            return self.NO_BODY_FILL
        return PALETTE[self.types[tool_body] % len(PALETTE)]

    def pages(self) -> int:
        if len(self.plan.steps) <= self.DETAIL:
            return 1
        return max(1, -(-len(blocks(self.plan.steps)) // self.PAGE_BLOCKS))

    def render(self, page: int = 1) -> str:
        pages = self.pages()
        if not 1 <= page <= pages:
            raise PlanError(f"the picture has {pages} page(s); no page {page}")
        if len(self.plan.steps) <= self.DETAIL:
            return self.detailed()
        return self.summarised(page, pages)

    def _head(self, width: int, height: int, subtitle: str) -> list[str]:
        plan = self.plan
        if plan.projects:  # the file beside the project's name; a program without one is titled by it
            subtitle = f"{plan.file_name}: {subtitle}"
        return [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
                f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="11">',
                f"<title>Workplan of {escape(plan.title)} ({escape(plan.program)})</title>",
                '<defs><marker id="arrow" markerWidth="8" markerHeight="8" refX="7" refY="4" orient="auto">'
                '<path d="M0,0 L8,4 L0,8 z" fill="#555"/></marker></defs>',
                f'<text class="title" x="10" y="24" font-size="15" font-weight="bold">{escape(plan.title)}</text>',
                f'<text x="10" y="44" fill="#444">{escape(subtitle)}</text>']

    def legend_entries(self, steps: list[Step] | tuple[Step, ...]) -> list[tuple[str, str]]:
        """(tool body type, the text of its legend entry) for the types of ``steps``, in order of
        first use: the type and the tools of it (at most :data:`LEGEND_TOOLS`, then how many more)."""
        tools: dict[str, dict[str, Thing]] = {}
        for s in steps:
            named = tools.setdefault(s.tool_body, {})
            if s.tool is not None:
                named.setdefault(s.tool.iri, s.tool)
        out = []
        for body, named in tools.items():
            names = [f"{t.label or '(no its_id)'} {t.ref}" for t in named.values()]
            more = len(names) - self.LEGEND_TOOLS
            listed = ", ".join(names[:self.LEGEND_TOOLS]) + (f" and {more} more" if more > 0 else "")
            text = f"{body}: {listed}" if listed else body
            out.append((body, text if len(text) <= self.LEGEND_CHARS else text[:self.LEGEND_CHARS - 1] + "\u2026"))
        return out

    def legend_height(self, steps: list[Step] | tuple[Step, ...]) -> int:
        return 24 * (min(len({s.tool_body for s in steps}), self.LEGEND + 1) + 2)

    def legend_width(self, steps: list[Step] | tuple[Step, ...]) -> int:
        """What the legend's longest entry needs (some 6.5 px a character of 11 px sans-serif)."""
        return max((42 + int(6.5 * len(text)) for _, text in self.legend_entries(steps)), default=0)

    def _legend(self, y: int, steps: list[Step] | tuple[Step, ...]) -> list[str]:
        out = [f'<text class="legend-title" x="10" y="{y + 11}" font-weight="bold">Tool body type (box colour)</text>']
        entries = self.legend_entries(steps)
        for k, (body, text) in enumerate(entries[:self.LEGEND]):
            ty = y + 24 * (k + 1)
            out.append(f'<g class="legend-type" data-type="{escape(body)}"><rect x="10" y="{ty}" width="16" height="14" '
                       f'fill="{self.type_colour(body)}" stroke="#333"/><text x="32" y="{ty + 11}">{escape(text)}'
                       "</text></g>")
        if len(entries) > self.LEGEND:
            out.append(f'<text class="legend-more" x="10" y="{y + 24 * (self.LEGEND + 1) + 11}" fill="#444">... and '
                       f"{len(entries) - self.LEGEND} more tool body types (each box names its tool)</text>")
        return out

    # -- one box per workingstep -------------------------------------------------------------------

    def row_height(self) -> int:
        return len(self.lanes) * self.LANE_H + 30

    def x(self, index: int) -> int:
        return self.LEFT + (index % self.row) * (self.BOX_W + self.GAP)

    def y(self, index: int, step: Step) -> int:
        lane = self.lane[step.setup.label if step.setup else "(no setup)"]
        return self.TOP + (index // self.row) * self.row_height() + lane * self.LANE_H + 20

    def detailed(self) -> str:
        steps = self.plan.steps
        index = {s.order: i for i, s in enumerate(steps)}
        rows = max(1, -(-len(steps) // self.row))
        width = self.x(min(len(steps), self.row) - 1) + self.BOX_W + 40 if steps else self.LEFT + 40
        width = max(width, self.legend_width(steps))
        legend_y = self.TOP + rows * self.row_height()
        height = legend_y + self.legend_height(steps)
        out = self._head(width, height, f"{len(steps)} workingsteps, {len(self.plan.tool_changes())} tool changes, "
                                        f"{len(self.lanes)} setup(s); arcs join roughing and finishing on a feature")
        plans = self._lane_workplans()
        for r in range(rows):
            for i, lane in enumerate(self.lanes):
                top = self.TOP + r * self.row_height() + i * self.LANE_H
                names = "".join(f'<text x="10" y="{top + self.LANE_H // 2 + 14 * (k + 1)}" fill="#444">{escape(t)}'
                                "</text>" for k, t in enumerate(_wrap(plans.get(lane, ""), 22, 2)) if t)
                out.append(f'<g class="lane" data-setup="{escape(lane)}" data-workplan="{escape(plans.get(lane, ""))}">'
                           f'<rect x="4" y="{top}" width="{width - 8}" '
                           f'height="{self.LANE_H - 6}" fill="{"#f7f7f7" if i % 2 == 0 else "#efefef"}"/>'
                           f'<text x="10" y="{top + self.LANE_H // 2}" font-weight="bold">{escape(lane)}</text>{names}</g>')
        for k, (a, b) in enumerate(zip(steps, steps[1:], strict=False)):
            x1, y1 = self.x(k) + self.BOX_W, self.y(k, a) + self.BOX_H // 2
            x2, y2 = self.x(k + 1), self.y(k + 1, b) + self.BOX_H // 2
            if (k + 1) % self.row:
                out.append(f'<line class="sequence" x1="{x1}" y1="{y1}" x2="{x2 - 2}" y2="{y2}" stroke="#555" '
                           f'marker-end="url(#arrow)"/>')
            else:  # the next row: down the right margin, back to its start
                bottom = self.TOP + (k // self.row + 1) * self.row_height() - 12
                out.append(f'<polyline class="sequence" points="{x1},{y1} {x1 + 8},{y1} {x1 + 8},{bottom} '
                           f'{x2 - 10},{bottom} {x2 - 10},{y2} {x2 - 2},{y2}" fill="none" stroke="#555" '
                           f'marker-end="url(#arrow)"/>')
        for s in steps:
            i = index[s.order]
            out.append(self.box(s, self.x(i), self.y(i, s)))
        for change in self.plan.tool_changes():
            i = index[change.order]
            cx, top = self.x(i) - self.GAP // 2, self.TOP + (i // self.row) * self.row_height()
            out.append(f'<g class="tool-change" data-order="{change.order}" data-from="{escape(change.before.ref)}" '
                       f'data-to="{escape(change.after.ref)}"><title>tool change before step {change.order}: '
                       f'{escape(change.before.label)} -&gt; {escape(change.after.label)}</title>'
                       f'<line x1="{cx}" y1="{top - 4}" x2="{cx}" y2="{top + self.row_height() - 24}" stroke="#d62728" '
                       f'stroke-width="2"/><text x="{cx}" y="{top - 8}" text-anchor="middle" fill="#d62728" '
                       f'font-weight="bold">T</text></g>')
        for feature, rough, finish in self.plan.rough_finish_pairs():
            i, j = index[rough], index[finish]
            x1, x2 = self.x(i) + self.BOX_W // 2, self.x(j) + self.BOX_W // 2
            y1, y2 = self.y(i, steps[i]) + self.BOX_H, self.y(j, steps[j]) + self.BOX_H
            bad = finish < rough
            dash = ' stroke-dasharray="5,3"' if bad else ""
            out.append(f'<path class="rough-finish{" precedence" if bad else ""}" data-feature="{escape(feature.ref)}" '
                       f'd="M{x1},{y1} Q{(x1 + x2) // 2},{max(y1, y2) + 26} {x2},{y2}" fill="none" '
                       f'stroke="{"#d62728" if bad else "#2c7fb8"}" stroke-width="1.5"{dash}><title>{escape(feature.label)} '
                       f'{escape(feature.ref)}: rough step {rough}, finish step {finish}</title></path>')
        out += self._legend(legend_y, steps)
        out.append("</svg>")
        return "\n".join(out) + "\n"

    def box(self, s: Step, x: int, y: int) -> str:
        """A workingstep's box: its full label (wrapped), #id and kind, the operation's class, the
        feature(s), the technology's numbers and the tool, a line each (the technology two); what
        does not fit ends in an ellipsis, and the tooltip has it all."""
        ink = _ink(self.colour(s))
        label = _wrap(f"{s.order}. {s.workingstep.label}", self.BOX_BOLD, 2)
        features = ", ".join(f"{f.label or f.cls} {f.ref}" for f in s.features)
        tool = f"{s.tool.label} {s.tool.ref}" if s.tool else NO_TOOL
        detail = [" ".join(filter(None, [s.workingstep.ref, s.kind]))]
        detail += _wrap(s.operation.cls, self.BOX_CHARS, 1) if s.operation else []
        detail += _wrap(features, self.BOX_CHARS, 1) if features else []
        detail += _wrap(s.technology.text(), self.BOX_CHARS, 2) if s.technology else []
        detail += _wrap(tool, self.BOX_CHARS, 1)
        title = (f"{s.order}. {s.workingstep.label} {s.workingstep.ref}; operation "
                 f"{s.operation.label + ' ' + s.operation.cls + ' ' + s.operation.ref if s.operation else '-'}; "
                 f"features {', '.join(f'{f.label} {f.ref} ({f.cls})' for f in s.features) or '-'}; technology "
                 f"{s.technology.ref + ' ' + s.technology.cls + ' ' + s.technology.text(', ') if s.technology else '-'}"
                 f"; tool {tool} ({s.tool_body})")
        lines = [f'<text x="{x + 6}" y="{y + 14 + 13 * k}" fill="{ink}" font-weight="bold">{escape(t)}</text>'
                 for k, t in enumerate(label)]
        lines += [f'<text x="{x + 6}" y="{y + 14 + 13 * len(label) + 12 * k}" fill="{ink}" font-size="10">'
                  f"{escape(t)}</text>" for k, t in enumerate(detail)]
        return (f'<g class="workingstep" data-order="{s.order}" data-ref="{escape(s.workingstep.ref)}" '
                f'data-tool="{escape(s.tool.ref) if s.tool else ""}" data-tool-body="{escape(s.tool_body)}">'
                f'<title>{escape(title)}</title>'
                f'<rect x="{x}" y="{y}" width="{self.BOX_W}" height="{self.BOX_H}" rx="5" fill="{self.colour(s)}" '
                f'stroke="#333"/>{"".join(lines)}</g>')

    # -- one box per block of steps with one setup and one tool -----------------------------------

    def summarised(self, page: int, pages: int) -> str:
        every = blocks(self.plan.steps)
        shown = every[(page - 1) * self.PAGE_BLOCKS:page * self.PAGE_BLOCKS]
        starts = {b.first.order for b in shown}
        changes = [c for c in self.plan.tool_changes() if c.order in starts]
        late = {p.finish for p in self.plan.precedence_violations()}
        pitch_x, pitch_y = self.BLOCK_W + self.GAP, self.BLOCK_H + 34
        rows = -(-len(shown) // self.BLOCK_ROW)
        steps = [s for b in shown for s in b.steps]
        width = max(20 + self.BLOCK_ROW * pitch_x + 20, self.legend_width(steps))
        legend_y = self.TOP + rows * pitch_y + 20
        height = legend_y + self.legend_height(steps)
        out = self._head(width, height, f"{len(self.plan.steps)} workingsteps, {len(self.plan.tool_changes())} tool "
                                        f"changes, {len(self.lanes)} setup(s); page {page} of {pages}: steps "
                                        f"{shown[0].first.order}-{shown[-1].last.order}, one box per run of steps "
                                        "with one setup and one tool")

        def at(k: int) -> tuple[int, int]:
            return 20 + (k % self.BLOCK_ROW) * pitch_x, self.TOP + (k // self.BLOCK_ROW) * pitch_y + 20

        for k, block in enumerate(shown):
            x, y = at(k)
            if k + 1 < len(shown):
                x2, y2 = at(k + 1)
                if (k + 1) % self.BLOCK_ROW:
                    out.append(f'<line class="sequence" x1="{x + self.BLOCK_W}" y1="{y + self.BLOCK_H // 2}" '
                               f'x2="{x2 - 2}" y2="{y2 + self.BLOCK_H // 2}" stroke="#555" marker-end="url(#arrow)"/>')
            out.append(self.block(block, x, y, any(s.order in late for s in block.steps)))
        first = {b.first.order: k for k, b in enumerate(shown)}
        for change in changes:
            x, y = at(first[change.order])
            out.append(f'<g class="tool-change" data-order="{change.order}" data-from="{escape(change.before.ref)}" '
                       f'data-to="{escape(change.after.ref)}"><title>tool change before step {change.order}: '
                       f'{escape(change.before.label)} -&gt; {escape(change.after.label)}</title>'
                       f'<line x1="{x - self.GAP // 2}" y1="{y - 6}" x2="{x - self.GAP // 2}" y2="{y + self.BLOCK_H + 6}" '
                       f'stroke="#d62728" stroke-width="2"/><text x="{x - self.GAP // 2}" y="{y - 9}" '
                       f'text-anchor="middle" fill="#d62728" font-weight="bold">T</text></g>')
        out += self._legend(legend_y, steps)
        out.append("</svg>")
        return "\n".join(out) + "\n"

    def block(self, b: Block, x: int, y: int, late: bool) -> str:
        s = b.first
        setup = s.setup.label if s.setup else "(no setup)"
        tool = f"{s.tool.label} {s.tool.ref}" if s.tool else "no tool"
        steps = f"step {s.order}" if len(b.steps) == 1 else f"steps {s.order}-{b.last.order} ({len(b.steps)})"
        refs = ", ".join(f"{t.order}. {t.workingstep.label} {t.workingstep.ref}" for t in b.steps[:20])
        more = f", ... ({len(b.steps) - 20} more)" if len(b.steps) > 20 else ""
        cls = "block precedence" if late else "block"
        ink = _ink(self.colour(s))
        stroke = ' stroke="#d62728" stroke-width="3"' if late else ' stroke="#333"'

        def cut(text: str, n: int = 25) -> str:
            return text if len(text) <= n else text[:n - 1] + "…"

        return (f'<g class="{cls}" data-first="{s.order}" data-last="{b.last.order}" data-steps="{len(b.steps)}" '
                f'data-setup="{escape(setup)}" data-tool="{escape(s.tool.ref) if s.tool else ""}" '
                f'data-tool-body="{escape(s.tool_body)}"><title>{escape(setup)}; tool {escape(tool)} '
                f'({escape(s.tool_body)}); {escape(refs + more)}'
                f'{"; a finishing step runs before roughing on its feature" if late else ""}</title>'
                f'<rect x="{x}" y="{y}" width="{self.BLOCK_W}" height="{self.BLOCK_H}" rx="5" fill="{self.colour(s)}"'
                f'{stroke}/><text x="{x + 6}" y="{y + 16}" fill="{ink}" font-weight="bold">{escape(steps)}</text>'
                f'<text x="{x + 6}" y="{y + 34}" fill="{ink}">{escape(cut(tool))}</text>'
                f'<text x="{x + 6}" y="{y + 52}" fill="{ink}">{escape(cut(setup))}</text></g>')


def _wrap(text: str, width: int, lines: int) -> list[str]:
    """``text`` in at most ``lines`` lines of ``width`` characters, broken at spaces; the last line
    ends with an ellipsis only when even that is not enough (the box's tooltip has it all)."""
    import textwrap

    out = textwrap.wrap(text, width, break_long_words=True) or [""]
    if len(out) > lines:
        rest = " ".join(out[lines - 1:])
        out = out[:lines - 1] + [rest[:width - 1] + "\u2026"]
    return out


def png(svg: str) -> bytes:
    """The picture as PNG; needs the ``png`` extra (``pip install 'stepnc-graph[png]'``, cairosvg)."""
    try:
        import cairosvg
    except (ImportError, OSError):  # not installed, or no cairo library on the system
        raise ImportError("PNG output needs cairosvg: pip install 'stepnc-graph[png]'") from None
    return bytes(cairosvg.svg2png(bytestring=svg.encode("utf-8")))
