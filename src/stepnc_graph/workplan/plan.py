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
needs matplotlib and knows nothing of lanes): setups are lanes, workingsteps boxes in execution
order coloured by tool, tool changes marked, rough -> finish pairs of a feature joined by arcs
(red and dashed when the finish comes first). PNG needs the ``png`` extra (cairosvg).
"""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from html import escape
from typing import TYPE_CHECKING, Any

import networkx as nx
import pyoxigraph as ox

from stepnc_graph.core.naming import ANALYSIS_NS, VOCABULARY_GRAPH, derived_graph_iri
from stepnc_graph.querying.query import PREFIXES

if TYPE_CHECKING:
    from stepnc_graph.store import GraphStore

PALETTE = ("#4e79a7", "#f28e2b", "#59a14f", "#b07aa1", "#76b7b2", "#edc948", "#ff9da7", "#9c755f", "#bab0ac",
           "#e15759")


class PlanError(ValueError):
    """No such program in the store, or a store the plan cannot be read from."""


@dataclass(frozen=True)
class Thing:
    """A workingstep, feature, tool, setup, workplan, ...: its IRI, its_id and #id."""

    iri: str
    label: str
    ref: str
    cls: str = ""


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


def _rows(store: GraphStore, graph: str, query: str) -> list[dict[str, Any]]:
    result = store.query(query, prefixes=PREFIXES,
                         default_graph=[ox.NamedNode(g) for g in (graph, derived_graph_iri(graph), VOCABULARY_GRAPH)],
                         named_graphs=[ox.NamedNode(graph)])
    return [{k.value: (None if row[k] is None else row[k].value) for k in result.variables} for row in result]


_STEPS = """
SELECT ?order ?ws ?wp ?setup ?tool ?op ?kind WHERE {
  ?step sga:executes ?ws ; sga:order ?order .
  OPTIONAL { ?step sga:workplan ?wp } OPTIONAL { ?step sga:setup ?setup } OPTIONAL { ?step sga:tool ?tool }
  OPTIONAL { ?ws attr:its_operation ?op
             OPTIONAL { ?op a ?rough FILTER(?rough = sga:RoughingOperation) }
             OPTIONAL { ?op a ?finish FILTER(?finish = sga:FinishingOperation) } }
  BIND(IF(BOUND(?rough), "rough", IF(BOUND(?finish), "finish", "")) AS ?kind)
} ORDER BY ?order"""
_EDGES = """
SELECT ?s ?p ?o WHERE {
  { ?s sga:feature ?o BIND("feature" AS ?p) }
  UNION { ?s attr:its_operation ?o BIND("operation" AS ?p) }
  UNION { ?x attr:its_operation ?s . ?s attr:its_technology ?o BIND("technology" AS ?p) }
  UNION { ?s stepnc:project.main_workplan ?o BIND("main_workplan" AS ?p) }
}"""
_ELEMENTS = """
SELECT ?s ?o ?i WHERE {
  { ?s stepnc:workplan.its_elements/rdf:rest* ?cell . ?cell rdf:first ?o ; sga:index ?i }
  UNION { ?s stepnc:parallel.branches|stepnc:non_sequential.its_elements|stepnc:selective.its_elements ?o }
  UNION { ?s stepnc:if_statement.true_branch ?o BIND(1 AS ?i) }
  UNION { ?s stepnc:if_statement.false_branch ?o BIND(2 AS ?i) }
  UNION { ?s stepnc:while_statement.body ?o BIND(1 AS ?i) }
}"""
_LABELS = """
SELECT ?x ?label ?n ?cls WHERE { GRAPH ?g { ?x p21:id ?n ; a ?cls } OPTIONAL { ?x attr:its_id ?label } }"""


class Plan:
    """The plan of one loaded program: ``graph`` (a networkx MultiDiGraph) and the execution ``steps``."""

    def __init__(self, program: str, steps: list[Step], graph: nx.MultiDiGraph) -> None:
        self.program = program
        self.steps = steps
        self.graph = graph

    # -- analyses ------------------------------------------------------------------------------

    def execution_order(self) -> list[Step]:
        return list(self.steps)

    def tool_changes(self) -> list[ToolChange]:
        """Steps whose tool differs from the one in the spindle (the last tool used before)."""
        out = []
        spindle: Thing | None = None
        for s in self.steps:
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
                       "tool_ref": s.tool.ref if s.tool else None, "kind": s.kind,
                       "features": [f.ref for f in s.features]} for s in self.steps],
            "graph": {"nodes": self.graph.number_of_nodes(), "edges": self.graph.number_of_edges()},
        }

    def to_json(self) -> str:
        return json.dumps(self.summary(), indent=2)

    def graphml(self) -> str:
        """GraphML for other tools (yEd, Gephi, Cytoscape): every attribute a string or number."""
        return "\n".join(nx.generate_graphml(self.graph, named_key_ids=True)) + "\n"

    def svg(self) -> str:
        return PlanPicture(self).render()


# -- building --------------------------------------------------------------------------------------


def _thing(info: dict[str, dict[str, Any]], iri: str | None) -> Thing | None:
    if iri is None:
        return None
    row = info.get(iri, {})
    return Thing(iri, row.get("label") or "", f"#{row['n']}" if row.get("n") else "",
                 (row.get("cls") or "").rsplit("#", 1)[-1])


def build_plan(store: GraphStore, graph: str | None = None) -> Plan:
    """The plan of the program in ``graph`` (or the store's only program)."""
    from stepnc_graph.graphs.vocabulary_graph import vocabulary_for_queries

    vocabulary_for_queries(store)
    programs = store.graphs()
    if graph is None:
        if len(programs) != 1:
            raise PlanError(f"the store holds {len(programs)} programs; choose one with --graph "
                            "(see `stepnc-graph info`)")
        graph = programs[0]
    if graph not in programs:
        raise PlanError(f"no loaded file with graph {graph}; `stepnc-graph info` lists them")
    info = {r["x"]: r for r in _rows(store, graph, _LABELS) if r["cls"] and not r["cls"].startswith(ANALYSIS_NS)}
    g: nx.MultiDiGraph = nx.MultiDiGraph(program=graph)

    def node(iri: str, kind: str) -> None:
        t = _thing(info, iri)
        assert t is not None
        g.add_node(iri, kind=kind, label=t.label, ref=t.ref, cls=t.cls)

    edges = _rows(store, graph, _EDGES)
    features: dict[str, list[str]] = defaultdict(list)
    for e in edges:
        if e["p"] == "feature":
            features[e["s"]].append(e["o"])
    steps: list[Step] = []
    for r in _rows(store, graph, _STEPS):
        ws = _thing(info, r["ws"])
        assert ws is not None
        steps.append(Step(int(r["order"]), ws, _thing(info, r["wp"]), _thing(info, r["setup"]), _thing(info, r["tool"]),
                          _thing(info, r["op"]), [f for f in (_thing(info, x) for x in sorted(features[r["ws"]]))
                                                  if f is not None], r["kind"] or ""))
    for s in steps:
        node(s.workingstep.iri, "workingstep")
        g.nodes[s.workingstep.iri].setdefault("order", s.order)
        if s.setup is not None:
            node(s.setup.iri, "setup")
            g.add_edge(s.setup.iri, s.workingstep.iri, key=f"runs{s.order}", kind="runs", order=s.order)
        if s.tool is not None:
            node(s.tool.iri, "tool")
    for a, b in zip(steps, steps[1:], strict=False):
        g.add_edge(a.workingstep.iri, b.workingstep.iri, key=f"next{a.order}", kind="next", order=a.order)
    kinds = {"feature": "feature", "operation": "operation", "technology": "technology", "main_workplan": "workplan"}
    for e in sorted(edges, key=lambda e: e["p"] == "technology"):  # operations before their technology
        if e["s"] in g or e["p"] == "main_workplan":
            if e["p"] == "main_workplan":
                node(e["s"], "project")
            node(e["o"], kinds[e["p"]])
            g.add_edge(e["s"], e["o"], key=e["p"], kind=e["p"])
    for e in _rows(store, graph, _ELEMENTS):
        if e["s"] in info and e["o"] in info:
            if e["s"] not in g:
                node(e["s"], "workplan")
            if e["o"] not in g:
                node(e["o"], "workplan")
            g.add_edge(e["s"], e["o"], key=f"element{e['i'] or 0}", kind="element", index=int(e["i"] or 0))
    for s in steps:
        if s.operation is not None and s.tool is not None:
            g.add_edge(s.operation.iri, s.tool.iri, key="tool", kind="tool")
    return Plan(graph, steps, g)


# -- the picture -----------------------------------------------------------------------------------


class PlanPicture:
    """An SVG of the plan: one lane per setup, workingsteps left to right in execution order.

    Every workingstep box is ``<g class="workingstep" data-order=.. data-ref=.. data-tool=..>``,
    every tool change ``<g class="tool-change" data-order=..>``, every rough/finish arc
    ``<path class="rough-finish" data-feature=..>`` (``precedence`` added when the finish comes
    first), so the picture can be checked (and styled) by machine.
    """

    BOX_W, BOX_H, GAP, LANE_H, LEFT, TOP = 120, 46, 14, 92, 150, 70

    def __init__(self, plan: Plan) -> None:
        self.plan = plan
        lanes: list[str] = []
        for s in plan.steps:
            name = s.setup.label if s.setup else "(no setup)"
            if name not in lanes:
                lanes.append(name)
        self.lanes = lanes
        tools: list[str] = []
        for s in plan.steps:
            if s.tool is not None and s.tool.iri not in tools:
                tools.append(s.tool.iri)
        self.tools = tools

    def colour(self, step: Step) -> str:
        if step.tool is None:
            return "#dddddd"
        return PALETTE[self.tools.index(step.tool.iri) % len(PALETTE)]

    def x(self, index: int) -> int:
        return self.LEFT + index * (self.BOX_W + self.GAP)

    def y(self, step: Step) -> int:
        return self.TOP + self.lanes.index(step.setup.label if step.setup else "(no setup)") * self.LANE_H + 20

    def render(self) -> str:
        steps = self.plan.steps
        index = {s.order: i for i, s in enumerate(steps)}
        width = self.x(len(steps)) + 40
        legend_y = self.TOP + len(self.lanes) * self.LANE_H + 30
        height = legend_y + 24 * (len(self.tools) + 2)
        out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
               f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="11">',
               f"<title>Workplan of {escape(self.plan.program)}</title>",
               '<defs><marker id="arrow" markerWidth="8" markerHeight="8" refX="7" refY="4" orient="auto">'
               '<path d="M0,0 L8,4 L0,8 z" fill="#555"/></marker></defs>',
               f'<text x="10" y="24" font-size="15" font-weight="bold">{escape(self.plan.program)}</text>',
               f'<text x="10" y="44" fill="#444">{len(steps)} workingsteps, {len(self.plan.tool_changes())} tool '
               f'changes, {len(self.lanes)} setup(s); arcs join roughing and finishing on a feature</text>']
        for i, lane in enumerate(self.lanes):
            top = self.TOP + i * self.LANE_H
            out.append(f'<g class="lane" data-setup="{escape(lane)}"><rect x="4" y="{top}" width="{width - 8}" '
                       f'height="{self.LANE_H - 6}" fill="{"#f7f7f7" if i % 2 == 0 else "#efefef"}"/>'
                       f'<text x="10" y="{top + self.LANE_H // 2}" font-weight="bold">{escape(lane)}</text></g>')
        for a, b in zip(steps, steps[1:], strict=False):
            x1, y1 = self.x(index[a.order]) + self.BOX_W, self.y(a) + self.BOX_H // 2
            x2, y2 = self.x(index[b.order]), self.y(b) + self.BOX_H // 2
            out.append(f'<line class="sequence" x1="{x1}" y1="{y1}" x2="{x2 - 2}" y2="{y2}" stroke="#555" '
                       f'marker-end="url(#arrow)"/>')
        for s in steps:
            out.append(self.box(s, self.x(index[s.order]), self.y(s)))
        for change in self.plan.tool_changes():
            cx = self.x(index[change.order]) - self.GAP // 2
            out.append(f'<g class="tool-change" data-order="{change.order}" data-from="{escape(change.before.ref)}" '
                       f'data-to="{escape(change.after.ref)}"><title>tool change before step {change.order}: '
                       f'{escape(change.before.label)} -&gt; {escape(change.after.label)}</title>'
                       f'<line x1="{cx}" y1="{self.TOP - 4}" x2="{cx}" y2="{legend_y - 22}" stroke="#d62728" '
                       f'stroke-width="2"/><text x="{cx}" y="{self.TOP - 8}" text-anchor="middle" fill="#d62728" '
                       f'font-weight="bold">T</text></g>')
        for feature, rough, finish in self.plan.rough_finish_pairs():
            a, b = steps[index[rough]], steps[index[finish]]
            x1, x2 = self.x(index[rough]) + self.BOX_W // 2, self.x(index[finish]) + self.BOX_W // 2
            y1, y2 = self.y(a) + self.BOX_H, self.y(b) + self.BOX_H
            bad = finish < rough
            dash = ' stroke-dasharray="5,3"' if bad else ""
            out.append(f'<path class="rough-finish{" precedence" if bad else ""}" data-feature="{escape(feature.ref)}" '
                       f'd="M{x1},{y1} Q{(x1 + x2) // 2},{max(y1, y2) + 26} {x2},{y2}" fill="none" '
                       f'stroke="{"#d62728" if bad else "#2c7fb8"}" stroke-width="1.5"{dash}><title>{escape(feature.label)} '
                       f'{escape(feature.ref)}: rough step {rough}, finish step {finish}</title></path>')
        for i, tool in enumerate(self.tools):
            t = next(s.tool for s in steps if s.tool is not None and s.tool.iri == tool)
            ty = legend_y + 24 * i
            out.append(f'<g class="legend-tool" data-ref="{escape(t.ref)}"><rect x="10" y="{ty}" width="16" height="14" '
                       f'fill="{PALETTE[i % len(PALETTE)]}"/><text x="32" y="{ty + 11}">{escape(t.label or "(no its_id)")} '
                       f'{escape(t.ref)} ({escape(t.cls)})</text></g>')
        out.append("</svg>")
        return "\n".join(out) + "\n"

    def box(self, s: Step, x: int, y: int) -> str:
        name = s.workingstep.label if len(s.workingstep.label) <= 14 else s.workingstep.label[:13] + "…"
        detail = " ".join(filter(None, [s.workingstep.ref, s.kind]))
        title = (f"{s.order}. {s.workingstep.label} {s.workingstep.ref}; tool {s.tool.label if s.tool else '-'} "
                 f"{s.tool.ref if s.tool else ''}; features {', '.join(f.label + ' ' + f.ref for f in s.features)}")
        return (f'<g class="workingstep" data-order="{s.order}" data-ref="{escape(s.workingstep.ref)}" '
                f'data-tool="{escape(s.tool.ref) if s.tool else ""}"><title>{escape(title)}</title>'
                f'<rect x="{x}" y="{y}" width="{self.BOX_W}" height="{self.BOX_H}" rx="5" fill="{self.colour(s)}" '
                f'stroke="#333"/><text x="{x + 6}" y="{y + 16}" fill="#fff" font-weight="bold">{s.order}. '
                f'{escape(name)}</text><text x="{x + 6}" y="{y + 34}" fill="#fff">{escape(detail)}</text></g>')


def png(svg: str) -> bytes:
    """The picture as PNG; needs the ``png`` extra (``pip install 'stepnc-graph[png]'``, cairosvg)."""
    try:
        import cairosvg
    except (ImportError, OSError):  # not installed, or no cairo library on the system
        raise ImportError("PNG output needs cairosvg: pip install 'stepnc-graph[png]'") from None
    return bytes(cairosvg.svg2png(bytestring=svg.encode("utf-8")))
