"""The plan of one loaded program (:class:`Plan`): its steps, the analyses computed from them in
Python, independently of the SPARQL library (tests compare the two) -- execution order, tool
changes, precedence (a finishing step before a roughing step on the same feature), workingsteps per
setup, tools shared across setups and the critical (most used) tool --, and its outputs: the
summary as JSON, GraphML of its networkx graph and the picture (:mod:`stepnc_graph.workplan.picture`)."""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from pathlib import PurePath
from typing import TYPE_CHECKING, Any
from urllib.parse import unquote

from stepnc_graph.workplan.model import PlanError, Precedence, Step, Thing, ToolChange
from stepnc_graph.workplan.picture import PlanPicture

if TYPE_CHECKING:
    import networkx as nx


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
