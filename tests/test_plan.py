"""The workplan as a networkx graph: analyses, GraphML, the SVG picture, `stepnc-graph plan`."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import networkx as nx
import pyoxigraph as ox
import pytest
from click.testing import CliRunner

import stepnc_graph as sg
from stepnc_graph.cli import main
from stepnc_graph.workplan.plan import Plan, PlanError, PlanPicture, build_plan
from stepnc_graph.store import GraphStore

from conftest import FIXTURES, ROOT

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
SLEEVE = FIXTURES / "query" / "sleeve_two_setups.stp"
STRUCTURES = FIXTURES / "query" / "structures.stp"
SVG = "{http://www.w3.org/2000/svg}"
RDF_TYPE = "http://www.w3.org/1999/02/22-rdf-syntax-ns#type"


def plan_of(path: Path) -> tuple[GraphStore, Plan]:
    store = sg.open_store(memory=True)
    sg.load(store, [path])
    return store, build_plan(store)


def test_analyses_of_the_sleeve() -> None:
    store, plan = plan_of(SLEEVE)
    assert [s.order for s in plan.execution_order()] == list(range(1, 14))
    assert [(c.order, c.before.ref, c.after.ref) for c in plan.tool_changes()] == [
        (5, "#100", "#110"), (6, "#110", "#120"), (7, "#120", "#130"), (9, "#130", "#100"), (10, "#100", "#140"),
        (11, "#140", "#100")]
    # the same answer as the SPARQL library, computed independently
    rows = sg.query(store, "tool-changes").rows
    assert [r["order"] for r in rows] == [c.order for c in plan.tool_changes()]
    assert [(p.feature.label, p.finish, p.rough) for p in plan.precedence_violations()] == [("OD 40", 11, 12)]
    assert {k: [s.order for s in v] for k, v in plan.workingsteps_per_setup().items()} == {
        "SETUP 1": list(range(1, 9)), "SETUP 2": list(range(9, 14))}
    assert plan.shared_tools() == {"#100": ["SETUP 1", "SETUP 2"]}
    tool, uses = plan.critical_tool()  # type: ignore[misc]
    assert (tool.label, tool.ref, uses) == ("T01 DCMT 11T304", "#100", 8)
    pairs = [(f.label, r, fin) for f, r, fin in plan.rough_finish_pairs()]
    assert ("OD 40", 12, 11) in pairs and ("FACE R", 1, 2) in pairs and ("M24X1.5 INNER", 7, 8) in pairs


def _reference_steps(store: GraphStore, graph: str) -> list[tuple[object, ...]]:
    """The steps as a look-up per thing reads them straight from the triples (slow, plainly right):
    a thing's #id and class from the program's graph, its its_id and the steps from the derived
    layer; a workingstep's operation the last by IRI, roughing before finishing."""
    from stepnc_graph.core.naming import ANALYSIS_NS, ATTRIBUTE_NS, P21_NS, derived_graph_iri
    from stepnc_graph.workplan.model import Thing

    program, derived = ox.NamedNode(graph), ox.NamedNode(derived_graph_iri(graph))

    def objects(node: Any, predicate: str, where: ox.NamedNode) -> list[Any]:
        return sorted((q.object for q in store.quads_for_pattern(node, ox.NamedNode(predicate), None, where)),
                      key=lambda o: o.value)

    def thing(node: Any) -> Thing | None:
        if node is None:
            return None
        ids, labels = objects(node, P21_NS + "id", program), objects(node, ATTRIBUTE_NS + "its_id", derived)
        classes = objects(node, RDF_TYPE, program)
        if not ids:
            return Thing(node.value, "", "", "")
        return Thing(node.value, labels[0].value if labels else "", f"#{ids[0].value}",
                     classes[0].value.rsplit("#", 1)[-1] if classes else "")

    def one(node: Any, name: str) -> Any:
        found = objects(node, ANALYSIS_NS + name, derived)
        return found[0] if found else None

    out: list[tuple[object, ...]] = []
    quads: list[Any] = list(store.quads_for_pattern(None, ox.NamedNode(ANALYSIS_NS + "order"), None, derived))
    steps = sorted((int(q.object.value), q.subject) for q in quads)
    starts = True
    for order, step in steps:
        ws = one(step, "executes")
        assert ws is not None
        operations = objects(ws, ATTRIBUTE_NS + "its_operation", derived)
        op = operations[-1] if operations else None
        kinds = {o.value.rsplit("#", 1)[-1] for o in objects(op, RDF_TYPE, derived)} if op else set()
        kind = "rough" if "RoughingOperation" in kinds else "finish" if "FinishingOperation" in kinds else ""
        out.append((order, thing(ws), thing(one(step, "workplan")), thing(one(step, "setup")),
                    thing(one(step, "tool")), thing(op), [thing(f) for f in objects(ws, ANALYSIS_NS + "feature", derived)],
                    kind, starts))
        starts = one(step, "next") is None
    return out


@pytest.mark.parametrize("path", [EXAMPLE, SLEEVE, STRUCTURES, FIXTURES / "editions" / "plate_fdis2001.stp"],
                         ids=lambda p: p.name)
def test_the_plan_reads_what_a_look_up_per_thing_reads(path: Path) -> None:
    """build_plan reads the steps in a few queries, joined in Python, for speed: the same steps, as
    data, as a look-up per thing gives (every field but the tool body and technology, tested above)."""
    store, plan = plan_of(path)
    found = [(s.order, s.workingstep, s.workplan, s.setup, s.tool, s.operation, s.features, s.kind, s.starts_root)
             for s in plan.steps]
    assert found == _reference_steps(store, plan.program) and found
    assert plan.steps == build_plan(store, network=False).steps  # the steps do not depend on the graph


@pytest.mark.parametrize("tool", ["TURNING_MACHINE_TOOL('T01 CNMG 120408',#101,(#103),120.,25.,$,7)",
                                  "CARTESIAN_POINT('T01',(0.,0.,0.))"], ids=["raw", "a-point"])
def test_a_step_naming_a_thing_of_an_unexpected_class_reads_it_as_a_look_up_does(tmp_path: Path, tool: str) -> None:
    """The plan reads the classes of what its steps name among the classes a tool, a workingstep, ... can
    have; a tool the file gets wrong (a raw instance, or a point) is looked up: the same #id and class."""
    text = EXAMPLE.read_text().replace("#100=TURNING_MACHINE_TOOL('T01 CNMG 120408',#101,(#103),120.,25.,$);",
                                       f"#100={tool};")
    path = tmp_path / "odd_tool.stp"
    path.write_text(text)
    store = sg.open_store(memory=True)
    sg.load(store, [path], lenient=True)
    plan = build_plan(store)
    found = [(s.order, s.workingstep, s.workplan, s.setup, s.tool, s.operation, s.features, s.kind, s.starts_root)
             for s in plan.steps]
    assert found == _reference_steps(store, plan.program)
    assert plan.steps[0].tool is not None and plan.steps[0].tool.ref == "#100"
    assert plan.steps[0].tool.cls in ("RawInstance", "cartesian_point")


def test_the_graph_holds_the_plan_structure() -> None:
    _, plan = plan_of(EXAMPLE)
    g = plan.graph
    kinds = nx.get_node_attributes(g, "kind")
    assert sum(k == "workingstep" for k in kinds.values()) == 8
    assert {k for k in kinds.values()} >= {"project", "workplan", "workingstep", "feature", "operation", "tool",
                                          "technology", "setup"}
    nxt = sorted((d["order"], g.nodes[u]["ref"], g.nodes[v]["ref"]) for u, v, d in g.edges(data=True)
                 if d["kind"] == "next")
    assert nxt[0] == (1, "#30", "#31") and len(nxt) == 7
    elements = sorted((g.nodes[u]["ref"], d["index"], g.nodes[v]["ref"]) for u, v, d in g.edges(data=True)
                      if d["kind"] == "element")
    assert elements[:3] == [("#2", 1, "#3"), ("#2", 2, "#4"), ("#3", 1, "#30")]
    # GraphML round-trips through networkx with every node and edge
    back = nx.parse_graphml(plan.graphml())
    assert back.number_of_nodes() == g.number_of_nodes() and back.number_of_edges() == g.number_of_edges()


def test_the_picture_holds_every_workingstep_and_tool_change() -> None:
    for path in (EXAMPLE, SLEEVE, STRUCTURES):
        _, plan = plan_of(path)
        root = ET.fromstring(plan.svg())
        groups = {g.get("class"): [] for g in root.iter(f"{SVG}g")}
        for g in root.iter(f"{SVG}g"):
            groups[g.get("class")].append(g)
        steps = [(int(g.get("data-order", 0)), g.get("data-ref")) for g in groups.get("workingstep", [])]
        assert steps == [(s.order, s.workingstep.ref) for s in plan.steps]
        changes = [(int(g.get("data-order", 0)), g.get("data-from"), g.get("data-to"))
                   for g in groups.get("tool-change", [])]
        assert changes == [(c.order, c.before.ref, c.after.ref) for c in plan.tool_changes()]
        lanes = [g.get("data-setup") for g in groups.get("lane", [])]
        rows = -(-len(plan.steps) // PlanPicture(plan).row)  # rows of at most ROW boxes, each with every setup's lane
        assert lanes == list(plan.workingsteps_per_setup()) * rows
        arcs = [p for p in root.iter(f"{SVG}path") if "rough-finish" in (p.get("class") or "")]
        assert len(arcs) == len(plan.rough_finish_pairs())
        assert sum("precedence" in (p.get("class") or "") for p in arcs) == len(plan.precedence_violations())


def test_boxes_are_coloured_by_tool() -> None:
    _, plan = plan_of(EXAMPLE)
    root = ET.fromstring(plan.svg())
    fill = {g.get("data-ref"): g.find(f"{SVG}rect").get("fill") for g in root.iter(f"{SVG}g")  # type: ignore[union-attr]
            if g.get("class") == "workingstep"}
    assert fill["#30"] == fill["#35"] != fill["#34"]  # T01 twice, T02 the groove


def test_plan_needs_one_program() -> None:
    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE, SLEEVE])
    with pytest.raises(PlanError, match="holds 2 programs"):
        build_plan(store)
    with pytest.raises(PlanError, match="no loaded file"):
        build_plan(store, "https://example.org/none")


def test_cli_plan_on_a_file_and_a_store(tmp_path: Path) -> None:
    runner = CliRunner()
    svg, graphml = tmp_path / "plan.svg", tmp_path / "plan.graphml"
    res = runner.invoke(main, ["plan", str(SLEEVE), "--svg", str(svg), "--graphml", str(graphml)])
    assert res.exit_code == 0, res.output
    assert "13 workingsteps, 6 tool changes" in res.stdout and "precedence: OD 40 #57" in res.stdout
    assert "critical tool: T01 DCMT 11T304 #100 (8 workingsteps)" in res.stdout
    assert ET.parse(svg).getroot().tag == f"{SVG}svg" and nx.read_graphml(graphml).number_of_nodes() > 13
    store = str(tmp_path / "store")
    assert runner.invoke(main, ["load", "--store", store, str(EXAMPLE), str(SLEEVE)]).exit_code == 0
    assert runner.invoke(main, ["plan", "--store", store]).exit_code == 2  # two programs: --graph needed
    res = runner.invoke(main, ["plan", "--store", store, "--graph",
                               "https://w3id.org/stepnc-graph/data/shaft_two_setups.stp", "--format", "json"])
    doc = json.loads(res.stdout)
    assert res.exit_code == 0 and doc["workingsteps"] == 8 and [c["order"] for c in doc["tool_changes"]] == [5, 6]
    assert runner.invoke(main, ["plan", str(tmp_path / "missing.stp")]).exit_code == 2


def test_png_needs_the_extra_or_writes_a_png(tmp_path: Path) -> None:
    out = tmp_path / "plan.png"
    res = CliRunner().invoke(main, ["plan", str(EXAMPLE), "--png", str(out)])
    try:
        import cairosvg  # noqa: F401
    except (ImportError, OSError):
        assert res.exit_code == 2 and "stepnc-graph[png]" in res.stderr
        return
    assert res.exit_code == 0 and out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_large_plan_is_drawn_in_pages_of_readable_width(tmp_path: Path) -> None:
    """Beyond PlanPicture.DETAIL steps the picture shows runs of steps with one setup and one tool,
    in rows of at most BLOCK_ROW, PAGE_BLOCKS a page: every step on exactly one page, in order, every
    tool change marked, every precedence error's finishing step in a marked run (was: one row,
    134 px a workingstep -- 496,526 px for a 200k-instance program)."""
    import sys

    sys.path.insert(0, str(ROOT / "bench"))
    from generate import replicate

    path = tmp_path / "sleeves.stp"
    replicate(SLEEVE, 115 * 40, path)  # 40 copies of the sleeve: 520 steps, 240 tool changes
    store = sg.open_store(memory=True)
    sg.load(store, [path])
    plan = build_plan(store, network=False)
    assert len(plan.steps) == 520 > PlanPicture.DETAIL
    seen: list[int] = []
    changes: list[int] = []
    late: list[int] = []
    for page in range(1, plan.pages() + 1):
        root = ET.fromstring(plan.svg(page))
        assert float(root.get("width", "0")) <= 1600
        entries = legend(root)  # the runs wear their tool body type's colour, named in the legend
        assert set(entries) == {"general_turning_tool", "grooving_tool", "knurling_tool", "turning_threading_tool",
                                "twist_drill"}
        for g in boxes(root, "block"):
            assert g.find(f"{SVG}rect").get("fill") == entries[g.get("data-tool-body", "")][0]  # type: ignore[union-attr]
        assert not [g for g in root.iter(f"{SVG}g") if g.get("class") == "workingstep"]
        for g in root.iter(f"{SVG}g"):
            kind = g.get("class", "")
            if kind.startswith("block"):
                first, last = int(g.get("data-first", 0)), int(g.get("data-last", 0))
                run = [s for s in plan.steps if first <= s.order <= last]
                assert int(g.get("data-steps", 0)) == len(run) and {
                    (s.setup.label if s.setup else "", s.tool.ref if s.tool else "") for s in run} == {
                    (g.get("data-setup"), g.get("data-tool"))}
                seen += [s.order for s in run]
                late += [s.order for s in run] if "precedence" in kind else []
            elif kind == "tool-change":
                changes.append(int(g.get("data-order", 0)))
    assert plan.pages() == 3 and seen == [s.order for s in plan.steps]
    assert changes == [c.order for c in plan.tool_changes()] and len(changes) == 240  # 6 a copy
    # each copy is a project: its first tool is loaded, not changed -- as the library counts
    assert changes == [r["order"] for r in sg.query(store, "tool-changes").rows]
    assert {p.finish for p in plan.precedence_violations()} <= set(late)
    with pytest.raises(PlanError, match="3 page"):
        plan.svg(4)
    runner = CliRunner()
    res = runner.invoke(main, ["plan", str(path), "--svg", str(tmp_path / "p2.svg"), "--page", "2"])
    assert res.exit_code == 0 and "page 2 of 3" in res.stderr
    assert ET.parse(tmp_path / "p2.svg").getroot().tag == f"{SVG}svg"
    res = runner.invoke(main, ["plan", str(path), "--svg", str(tmp_path / "p9.svg"), "--page", "9"])
    assert res.exit_code == 2 and "no page 9" in res.stderr


def test_a_plan_without_its_graph_says_so() -> None:
    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE])
    plan = build_plan(store, network=False)
    assert [s.order for s in plan.steps] == list(range(1, 9)) and plan.tool_changes()
    with pytest.raises(PlanError, match="network=True"):
        plan.graph  # noqa: B018


# -- the picture's title, its legend by tool body type, what each box says (issue 31, item 12) --


def variant(tmp_path: Path, name: str, *edits: tuple[str, str]) -> Path:
    """The shaft example with text replaced (each edit must apply), written as ``name``."""
    text = EXAMPLE.read_text()
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def svg_of(path: Path) -> ET.Element:
    return ET.fromstring(plan_of(path)[1].svg())


def heading(root: ET.Element) -> str:
    return "".join(next(t for t in root.iter(f"{SVG}text") if t.get("class") == "title").itertext())


def legend(root: ET.Element) -> dict[str, tuple[str, str]]:
    """Tool body type -> (swatch fill, the entry's text), in the legend's order."""
    out = {}
    for g in root.iter(f"{SVG}g"):
        if g.get("class") == "legend-type":
            rect = g.find(f"{SVG}rect")
            assert rect is not None
            out[g.get("data-type", "")] = (rect.get("fill", ""), "".join(g.itertext()))
    return out


def boxes(root: ET.Element, kind: str = "workingstep") -> list[ET.Element]:
    return [g for g in root.iter(f"{SVG}g") if (g.get("class") or "").split()[:1] == [kind]]


def test_the_picture_and_the_summary_are_titled_by_the_project() -> None:
    _, plan = plan_of(EXAMPLE)
    assert plan.title == "SHAFT-42" and plan.projects == ["SHAFT-42"]
    root = ET.fromstring(plan.svg())
    assert heading(root) == "SHAFT-42"
    assert "SHAFT-42" in (root.findtext(f"{SVG}title") or "")
    done = CliRunner().invoke(main, ["plan", str(EXAMPLE)])
    first = done.stdout.splitlines()[0]
    assert done.exit_code == 0 and first.startswith("SHAFT-42 (") and first.endswith("8 workingsteps, 2 tool changes")
    doc = json.loads(CliRunner().invoke(main, ["plan", str(EXAMPLE), "--format", "json"]).stdout)
    assert doc["title"] == "SHAFT-42" and doc["projects"] == ["SHAFT-42"]


def test_a_program_without_a_project_is_titled_by_its_file_name(tmp_path: Path) -> None:
    path = variant(tmp_path, "no_project.stp", ("#1=PROJECT('SHAFT-42',#2,(#10),$,$,$);\n", ""))
    _, plan = plan_of(path)
    assert plan.projects == [] and plan.title == "no_project.stp"
    assert heading(ET.fromstring(plan.svg())) == "no_project.stp"
    # loaded under another graph IRI, the file it was read from still names it
    store = sg.open_store(memory=True)
    sg.load(store, [path], base_iri="https://example.org/programs/42")
    assert build_plan(store).title == "no_project.stp"


def test_the_legend_names_each_tool_body_type_and_boxes_wear_its_colour(tmp_path: Path) -> None:
    root = svg_of(EXAMPLE)
    entries = legend(root)
    assert list(entries) == ["general_turning_tool", "grooving_tool"]
    assert "T01 CNMG 120408 #100" in entries["general_turning_tool"][1]
    assert "T02 GROOVING 3MM #110" in entries["grooving_tool"][1]
    body = {"#100": "general_turning_tool", "#110": "grooving_tool"}  # the tool bodies #101 and #111
    steps = boxes(root)
    assert len(steps) == 8
    for g in steps:
        assert g.get("data-tool-body") == body[g.get("data-tool", "")]
        assert g.find(f"{SVG}rect").get("fill") == entries[body[g.get("data-tool", "")]][0]  # type: ignore[union-attr]
    assert entries["general_turning_tool"][0] != entries["grooving_tool"][0]
    # two tools with one body type: one colour, one legend entry naming both
    same = variant(tmp_path, "two_turning_tools.stp", ("GROOVING_TOOL(#112,.NEUTRAL.,6.,$,25.,25.,.CCW.,3.,0.2)",
                                                       "GENERAL_TURNING_TOOL(#112,.NEUTRAL.,6.,$,25.,25.,.CCW.)"))
    root = svg_of(same)
    entries = legend(root)
    assert list(entries) == ["general_turning_tool"]
    assert "T01 CNMG 120408 #100" in entries["general_turning_tool"][1] and "T02 GROOVING 3MM #110" in \
        entries["general_turning_tool"][1]
    assert {g.find(f"{SVG}rect").get("fill") for g in boxes(root)} == {entries["general_turning_tool"][0]}  # type: ignore[union-attr]


def test_the_legend_names_steps_without_a_tool_body_or_a_tool(tmp_path: Path) -> None:
    path = variant(tmp_path, "no_body.stp", ("'T02 GROOVING 3MM',#111,", "'T02 GROOVING 3MM',$,"))
    root = svg_of(path)
    entries = legend(root)
    assert list(entries) == ["general_turning_tool", "no tool body"]
    assert "T02 GROOVING 3MM #110" in entries["no tool body"][1]
    [groove] = [g for g in boxes(root) if g.get("data-tool") == "#110"]
    assert groove.get("data-tool-body") == "no tool body"
    assert groove.find(f"{SVG}rect").get("fill") == entries["no tool body"][0]  # type: ignore[union-attr]
    root = svg_of(STRUCTURES)  # rapid movements: no tool at all
    entries = legend(root)
    assert list(entries) == ["no tool"]
    assert {g.find(f"{SVG}rect").get("fill") for g in boxes(root)} == {entries["no tool"][0]}  # type: ignore[union-attr]


def test_the_sleeve_legend_has_turning_and_milling_tool_bodies() -> None:
    entries = legend(svg_of(SLEEVE))
    assert list(entries) == ["general_turning_tool", "grooving_tool", "knurling_tool", "turning_threading_tool",
                             "twist_drill"]
    assert len({fill for fill, _ in entries.values()}) == 5


def test_each_box_shows_its_operation_feature_technology_and_tool() -> None:
    _, plan = plan_of(SLEEVE)
    root = ET.fromstring(plan.svg())
    texts = {g.get("data-ref"): " ".join(t.text or "" for t in g.iter(f"{SVG}text")) for g in boxes(root)}
    first = texts["#30"]  # the sleeve's first workingstep
    ws = next(s for s in plan.steps if s.workingstep.ref == "#30")
    assert ws.operation is not None and ws.operation.cls in first
    assert all(f.label in first for f in ws.features) and ws.tool is not None and ws.tool.label in first
    assert ws.technology is not None and "feedrate=" in first
    # the drilling step: a milling technology's feedrate and spindle speed, the drill
    drill = next(s for s in plan.steps if s.workingstep.label == "WS10 DRILL 18")
    text = texts[drill.workingstep.ref]
    assert "feedrate=0.12" in text and "spindle=1400" in text and "T05 DRILL 18" in text
    assert "drilling" in text
    assert drill.technology is not None and dict(drill.technology.values) == {"feedrate": "0.12", "spindle": "1400"}
    # a turning technology's speed comes from its spindle speed entity
    _, shaft = plan_of(EXAMPLE)
    assert shaft.steps[0].technology is not None
    assert shaft.steps[0].technology.values == (("feedrate", "0.25"), ("speed", "180"), ("max_speed", "2500"))


def test_a_2001_program_names_its_tool_bodies_by_its_own_classes() -> None:
    """The 2001 edition's centre drill is ``center_drill``, the same class as 2002's ``centerdrill``
    (owl:equivalentClass): its body type is named as the program gives it, not 'no tool body'."""
    _, plan = plan_of(FIXTURES / "editions" / "plate_fdis2001.stp")
    assert [s.tool_body for s in plan.steps] == ["center_drill", "boring_tool"]
    assert list(legend(ET.fromstring(plan.svg()))) == ["center_drill", "boring_tool"]
    assert plan.steps[0].technology is not None and plan.steps[0].technology.cls == "milling_technology"
