"""Reading a loaded program's plan from the store (:func:`build_plan`): the derived layer's execution
steps (:mod:`stepnc_graph.loading.derive`) and what they name, in a few SPARQL queries whose rows
are joined in Python, and, when asked for, the networkx graph: project -> workplans (nested,
``element`` edges with their index) -> workingsteps, which are linked in execution order (``next``
edges carry the order) and to their feature(s), operation, tool and technology; setups group the
workingsteps that run in them (``runs`` edges)."""

from __future__ import annotations

import csv
import io
from collections import defaultdict
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.core.errors import listed_by, option
from stepnc_graph.core.naming import (
    STEPNC_NS,
    VOCABULARY_GRAPH,
    derived_graph_iri,
    instance_id,
    program_graphs,
)
from stepnc_graph.querying.query import PREFIXES
from stepnc_graph.workplan.analyses import Plan
from stepnc_graph.workplan.model import NO_TOOL, NO_TOOL_BODY, PlanError, Step, Technology, Thing
from stepnc_graph.workplan.picture import PlanPicture

if TYPE_CHECKING:
    import networkx as nx

    from stepnc_graph.store.contract import Store


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
# A program of 100k instances has 9,000 steps and 30,000 things to show: a look-up per thing, or a
# property path per list, took most of the time; now most of it goes to the joins (some 3 us a row
# each) and to writing out the terms (an IRI 2-6 us, a number 1): the steps' facts come in one
# query, an operation's IRI once a step (not again as the subject of its kind), a class as a number.
#: one row per step (more only for a workingstep of several operations, or an operation that both
#: roughs and finishes): its workingstep, workplan, setup, tool, the workingstep's operation and
#: whether that roughs or finishes, and whether the step has a next one in its root of the order
_STEPS = """
SELECT ?order ?ws ?wp ?setup ?tool ?op ?kind ?more WHERE {
  { SELECT ?step ?order WHERE { ?step sga:order ?order } }
  { SELECT ?step ?ws WHERE { ?step sga:executes ?ws } }
  OPTIONAL { { SELECT ?step ?wp WHERE { ?step sga:workplan ?wp } } }
  OPTIONAL { { SELECT ?step ?setup WHERE { ?step sga:setup ?setup } } }
  OPTIONAL { { SELECT ?step ?tool WHERE { ?step sga:tool ?tool } } }
  OPTIONAL { { SELECT ?step ?next WHERE { ?step sga:next ?next } } }
  OPTIONAL { { SELECT ?ws ?op ?kind WHERE {
    { SELECT ?ws ?op WHERE { ?ws attr:its_operation ?op } }
    OPTIONAL { { SELECT ?op ?kind WHERE {
      { ?op a sga:RoughingOperation BIND("rough" AS ?kind) } UNION { ?op a sga:FinishingOperation BIND("finish" AS ?kind) }
    } } }
  } } }
  BIND(IF(BOUND(?next), 1, 0) AS ?more)
}"""
#: the workingsteps' features
_FEATURES = "SELECT ?ws ?f WHERE { ?ws sga:feature ?f }"
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
  { ?s stepnc:parallel.branches ?o BIND(0 AS ?i) } UNION { ?s stepnc:non_sequential.its_elements ?o BIND(0 AS ?i) }
  UNION { ?s stepnc:selective.its_elements ?o BIND(0 AS ?i) }
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
#: what the plan shows of a thing (its_id and class as the program's graph types it; a row per
#: class), for the things ``NAMED`` names; the class as its place in ``CLASSES`` (``(<class> k)``
#: pairs), a number, not an IRI, for each of 30,000 things (0.1 CPU-s less at 100k instances). Only
#: the file's instances have a class there (every one has: a class of its entity, or ``p21:Raw``),
#: and each such IRI is the graph's ``i<#id>`` (:func:`~stepnc_graph.core.naming.instance_iri`): the
#: ``#id`` is read from the IRI, not by joining the program's 100,000 ``p21:id`` values (0.1 CPU-s).
#: ``CLASSES`` holds the classes the things are expected to have (``_STEP_ROOTS``), not those of the
#: points and placements that make most of a program (0.08 CPU-s); a thing of none of them (or not
#: in the program) is looked up (:func:`_look_up`).
_THINGS = """
SELECT ?x ?label ?k WHERE {
  { SELECT DISTINCT ?x WHERE { NAMED } }
  OPTIONAL { { SELECT ?x ?k WHERE { VALUES (?cls ?k) { CLASSES } GRAPH ?g { ?x a ?cls } } } }
  OPTIONAL { { SELECT ?x ?label WHERE { ?x attr:its_id ?label } } }
}"""
#: the classes the program's graph types instances with (the derived layer counts each; a scan of
#: the program's 100,000 types took 0.07 CPU-s)
_COUNTED = "SELECT DISTINCT ?cls WHERE { ?count sga:countedClass ?cls }"
#: what the steps name, as a UNION (the same as a property path of alternatives, ``sga:executes|...``,
#: which Oxigraph evaluates four times slower: 0.1 CPU-s at 100k instances); and the entities whose
#: subclasses they are (an executable: a workingstep or a workplan, ...)
_STEP_THINGS = ("{ ?s sga:executes ?x } UNION { ?s sga:workplan ?x } UNION { ?s sga:setup ?x } UNION { ?s sga:tool ?x } "
                "UNION { ?s sga:feature ?x } UNION { ?s attr:its_operation ?x }")
_STEP_ROOTS = ("executable", "setup", "machining_tool", "manufacturing_feature", "operation")
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
_MORE_ROOTS = ("technology", "project")
#: the same for a few things by IRI
_THING = """
SELECT ?x ?label ?n ?cls WHERE { GRAPH ?g { ?x p21:id ?n OPTIONAL { ?x a ?cls } } OPTIONAL { ?x attr:its_id ?label } }"""


def _thing(info: dict[str, Thing], iri: str | None) -> Thing | None:
    if not iri:
        return None
    return info.get(iri) or Thing(iri, "", "", "")


def _things(store: Store, graph: str, named: str, roots: tuple[str, ...], info: dict[str, Thing]) -> None:
    """Add the Things ``named`` names (a SPARQL pattern binding ``?x``; instances of ``roots`` and
    their subclasses, as a rule) to ``info``: those the program's graph holds (the others stay out
    of ``info``: no ``#id``, label or class). A thing of several classes (a complex instance) gets
    one, of ``roots`` if it has one."""
    classes = sorted({cls for (cls,) in _rows(store, graph, _COUNTED)})
    expected = set(_class_list(store, graph, roots))
    values = " ".join(f"(<{cls}> {k})" for k, cls in enumerate(classes) if cls in expected) or "(<urn:none> 0)"
    names = [cls.rsplit("#", 1)[-1] for cls in classes]
    odd: list[str] = []
    for x, label, k in _rows(store, graph, _THINGS.replace("NAMED", named).replace("CLASSES", values)):
        n = instance_id(graph, x) if k else None
        if n is not None:
            info[x] = Thing(x, label, f"#{n}", names[int(k)])
        else:  # of another class, not in the program, or not an IRI the loader mints
            odd.append(x)
    if odd:
        _look_up(store, graph, odd, info)


def _look_up(store: Store, graph: str, iris: list[str], info: dict[str, Thing]) -> None:
    """Add the Things ``iris`` (those the program's graph gives an ``#id``) to ``info``, a look-up each."""
    values = " ".join(f"<{x}>" for x in iris)
    for x, label, n, cls in _rows(store, graph, _THING.replace("WHERE {", f"WHERE {{ VALUES ?x {{ {values} }}", 1)):
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
    return " ".join(f"<{cls}>" for cls in _class_list(store, graph, (root,))) or "<urn:none>"


def _class_list(store: Store, graph: str, roots: tuple[str, ...]) -> list[str]:
    """The vocabulary's classes under the entities ``roots`` (and their older editions' names), sorted."""
    # a query a root: the path from a constant (from a VALUES variable, plan failed on Virtuoso 7:
    # tests/test_live_stores.py)
    return sorted({cls for root in roots for (cls,) in _rows(store, graph, _CLASSES.replace("ROOT", f"<{STEPNC_NS}{root}>"))})


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


def _steps(store: Store, graph: str, info: dict[str, Thing],
           network: bool = True) -> tuple[list[Step], list[tuple[str, str, str]]]:
    """The execution steps in order, with the things they name, whether they rough or finish and
    their tool's body type (:func:`_add_technologies` adds the technologies); and, for the
    ``network``, the workingsteps' ``feature`` and ``operation`` edges."""
    features: dict[str, set[str]] = defaultdict(set)
    for ws, f in _rows(store, graph, _FEATURES):
        features[ws].add(f)
    edges = {(ws, "feature", f) for ws, found in features.items() for f in found} if network else set()
    grouped: dict[int, list[list[str]]] = defaultdict(list)
    for row in _rows(store, graph, _STEPS):
        grouped[int(row[0])].append(row)
    bodies = _tool_bodies(store, graph)
    steps: list[Step] = []
    more = "0"
    for order, rows in sorted(grouped.items()):
        _, ws, wp, setup, tool = rows[0][:5]
        # a workingstep of several operations (none in ISO 14649) shows the last by IRI; an
        # operation that both roughs and finishes counts as roughing
        op = max(r[5] for r in rows)
        kinds = {r[6] for r in rows if r[5] == op}
        if network:
            edges.update((ws, "operation", r[5]) for r in rows if r[5])
        steps.append(Step(order, info.get(ws) or Thing(ws, "", "", ""), _thing(info, wp), _thing(info, setup),
                          _thing(info, tool), _thing(info, op),
                          [f for f in (_thing(info, x) for x in sorted(features.get(ws, ()))) if f is not None],
                          "rough" if "rough" in kinds else "finish" if "finish" in kinds else "",
                          starts_root=more == "0", tool_body=bodies.get(tool, NO_TOOL_BODY) if tool else NO_TOOL))
        more = rows[0][7]
    return steps, sorted(edges)


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
    _things(store, graph, _STEP_THINGS, _STEP_ROOTS, info)
    steps, edges = _steps(store, graph, info, network)
    projects, source = _projects(store, graph), next((src for (src,) in _rows(store, graph, _SOURCE)), None)
    if network or len(steps) <= PlanPicture.DETAIL:
        _add_technologies(store, graph, steps)
    if not network:
        return Plan(graph, steps, projects=projects, source=source)
    _things(store, graph, _MORE_THINGS, _MORE_ROOTS, info)
    edges += sorted({(s, p, o) for s, p, o in _rows(store, graph, _MORE_EDGES)}, key=lambda e: (e[1], e))
    elements = _elements(store, graph)
    others = sorted({x for s, o, _ in elements for x in (s, o)
                     if x not in info and x.startswith(("http:", "https:")) and ">" not in x})
    if others:
        _look_up(store, graph, others, info)
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
