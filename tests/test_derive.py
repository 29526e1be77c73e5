"""The derived layer and the vocabulary graph: contents, round trip, atomic replace and unload."""

from __future__ import annotations

import sys
from pathlib import Path

import pyoxigraph as ox
import pytest

import stepnc_graph as sg
from stepnc_graph.loading.derive import compile_rules, iso14649_rules
from stepnc_graph.core.naming import (
    ANALYSIS_NS,
    ATTRIBUTE_NS,
    STEPNC_NS,
    VOCABULARY_GRAPH,
    derived_graph_iri,
    execution_step_iri,
)
from stepnc_graph.store import GraphStore
from stepnc_graph.graphs.vocabulary_graph import (
    DIGEST,
    stored_digest,
    vocabulary_digest,
    vocabulary_files,
    vocabulary_for_queries,
    vocabulary_status,
)
from stepnc_graph.core.naming import listed_graphs

from conftest import FIXTURES, ROOT

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
STRUCTURES = FIXTURES / "query" / "structures.stp"
SLEEVE = FIXTURES / "query" / "sleeve_two_setups.stp"
PREFIXES = (f"PREFIX stepnc: <{STEPNC_NS}> PREFIX sga: <{ANALYSIS_NS}> PREFIX attr: <{ATTRIBUTE_NS}> "
            "PREFIX rdfs: <http://www.w3.org/2000/01/rdf-schema#> PREFIX p21: <https://w3id.org/stepnc-graph/p21#> ")


def rows(store: GraphStore, graph: str, query: str) -> list[tuple[str, ...]]:
    """Run ``query`` over ``graph``'s derived layer (default graph); values as short strings."""
    result = store.query(PREFIXES + query, default_graph=[ox.NamedNode(derived_graph_iri(graph))])
    prefix = graph + "/"
    return [tuple("" if t is None else str(t.value).removeprefix(prefix) for t in r) for r in result]


@pytest.fixture(scope="module")
def example() -> tuple[GraphStore, str]:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EXAMPLE])
    vocabulary_for_queries(store)  # a throw-away store gets the vocabulary when queries need it
    return store, r.graph


def test_class_closure_for_process_instances_only(example: tuple[GraphStore, str]) -> None:
    store, g = example
    types = rows(store, g, "SELECT ?c WHERE { <%s/i50> a ?c } ORDER BY ?c" % g)
    assert [t[0].rsplit("#", 1)[1] for t in types] == [
        "RoughingOperation", "facing", "machining_operation", "operation", "turning_machining_operation"]
    assert rows(store, g, "SELECT ?c WHERE { <%s/i201> a ?c }" % g) == []  # a cartesian point: nothing
    assert rows(store, g, "SELECT ?c WHERE { <%s/i260> a ?c }" % g) == []  # a tolerance: left out
    # the data graph's own rdf:type is not repeated, so a union of both graphs has no duplicates
    assert rows(store, g, "SELECT ?c WHERE { <%s/i50> a stepnc:facing_rough }" % g) == []


def test_generic_values_and_labels(example: tuple[GraphStore, str]) -> None:
    store, g = example
    assert rows(store, g, "SELECT ?v ?l WHERE { <%s/i30> attr:its_id ?v ; rdfs:label ?l }" % g) == [
        ("WS1 FACE RIGHT ROUGH", "WS1 FACE RIGHT ROUGH")]
    ops = rows(store, g, "SELECT ?ws ?tool WHERE { ?ws attr:its_operation/attr:its_tool ?tool } ORDER BY ?ws")
    assert [o[1] for o in ops] == ["i100"] * 4 + ["i110"] + ["i100"] * 3
    # a value that is a blank node (a list head) is the same node as in the file's graph
    both = store.query(PREFIXES + f"SELECT ?h WHERE {{ GRAPH <{g}> {{ <{g}/i3> stepnc:workplan.its_elements ?h }} "
                                  f"GRAPH <{derived_graph_iri(g)}> {{ <{g}/i3> attr:its_elements ?h }} }}")
    assert len(list(both)) == 1
    # empty its_id gives no label; a resource's attributes are not materialised
    assert rows(store, g, "SELECT ?s WHERE { ?s attr:coordinates ?c }") == []


def test_list_positions_on_the_cells_of_process_lists(example: tuple[GraphStore, str]) -> None:
    store, g = example
    found = store.query(PREFIXES + f"SELECT ?ws ?i WHERE {{ GRAPH <{g}> {{ <{g}/i3> stepnc:workplan.its_elements "
                                   f"?h . ?h <http://www.w3.org/1999/02/22-rdf-syntax-ns#rest>* ?c . ?c "
                                   f"<http://www.w3.org/1999/02/22-rdf-syntax-ns#first> ?ws }} "
                                   f"GRAPH <{derived_graph_iri(g)}> {{ ?c sga:index ?i }} }} ORDER BY ?i")
    assert [(r["ws"].value.rsplit("/", 1)[1], int(r["i"].value)) for r in found] == [
        ("i30", 1), ("i31", 2), ("i32", 3), ("i33", 4), ("i34", 5)]


def test_execution_order_of_the_example(example: tuple[GraphStore, str]) -> None:
    store, g = example
    steps = rows(store, g, "SELECT ?o ?ws ?wp ?setup ?next WHERE { ?s a sga:ExecutionStep ; sga:order ?o ; "
                           "sga:executes ?ws ; sga:workplan ?wp ; sga:setup ?setup OPTIONAL { ?s sga:next ?next } } "
                           "ORDER BY ?o")
    assert steps == [(str(n), f"i{30 + n - 1}", "i3" if n <= 5 else "i4", "i20" if n <= 5 else "i24",
                      f"derived/step{n + 1}" if n < 8 else "") for n in range(1, 9)]
    assert execution_step_iri(g, 3) == f"{g}/derived/step3"
    features = rows(store, g, "SELECT ?ws ?f WHERE { ?ws sga:feature ?f } ORDER BY ?ws")
    assert ("i34", "i42") in features and len(features) == 8


def test_steps_carry_their_program_workingstep_and_operation() -> None:
    """sga:program, sga:workingstepId, sga:operationId and sga:operationClass on each step are what
    the file's graph says of the step's workingstep and its operation (read there independently)."""
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [SLEEVE])
    g = r.graph
    on_steps = rows(store, g, "SELECT ?o ?p ?w ?n ?c WHERE { ?s sga:order ?o ; sga:program ?p ; "
                              "sga:workingstepId ?w ; sga:operationId ?n ; sga:operationClass ?c } ORDER BY ?o")
    steps = rows(store, g, "SELECT ?o ?ws WHERE { ?s sga:order ?o ; sga:executes ?ws } ORDER BY ?o")
    assert len(on_steps) == len(steps) == 13
    program = store.query(PREFIXES + f"SELECT ?ws ?w ?n ?c WHERE {{ GRAPH <{g}> {{ ?ws p21:id ?w ; "
                                     "attr:its_operation|stepnc:machining_workingstep.its_operation|"
                                     "stepnc:turning_workingstep.its_operation ?op . ?op p21:id ?n ; a ?c } }")
    truth = {r["ws"].value.removeprefix(g + "/"): (r["w"].value, r["n"].value, r["c"].value) for r in program}
    for (order, ws), (order2, graph, w, n, c) in zip(steps, on_steps, strict=True):
        assert order == order2 and graph == g and truth[ws] == (w, n, c)


def test_steps_carry_the_names_and_tool_their_rows_show() -> None:
    """A step's operation, the names (its_id) of its workingstep, operation, workplan, setup and tool,
    the tool's #id and its body's class (sga:operation, sga:workingstepName ... sga:toolBodyClass,
    layer version 3) are what the file's graph says of them, read there independently; every step
    of the sleeve has them all."""
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [SLEEVE])
    g = r.graph
    shown = ("operation", "workingstepName", "operationName", "workplanName", "setupName", "toolName", "toolId",
             "toolBodyClass")
    on_steps = rows(store, g, "SELECT ?o " + " ".join(f"?{n}" for n in shown) + " WHERE { ?s sga:order ?o ; "
                    + " ; ".join(f"sga:{n} ?{n}" for n in shown) + " } ORDER BY ?o")
    truth = rows(store, g, f"SELECT ?o ?operation ?w ?op ?wp ?su ?t ?tn ?bc WHERE {{ ?s sga:order ?o ; sga:executes ?ws ; "
                 f"sga:workplan ?plan ; sga:setup ?setup ; sga:tool ?tool . GRAPH <{g}> {{ ?ws ?i1 ?w ; ?p ?operation . "
                 "?operation ?i2 ?op . ?plan ?i3 ?wp . ?setup ?i4 ?su . ?tool ?i5 ?t ; p21:id ?tn ; "
                 "stepnc:cutting_tool.its_tool_body ?body . ?body a ?bc } "
                 "FILTER(STRENDS(STR(?i1), '.its_id') && STRENDS(STR(?p), 'workingstep.its_operation') && "
                 "STRENDS(STR(?i2), '.its_id') && STRENDS(STR(?i3), '.its_id') && STRENDS(STR(?i4), '.its_id') && "
                 "STRENDS(STR(?i5), '.its_id')) } ORDER BY ?o")
    assert len(on_steps) == len(truth) == 13 and on_steps == truth


def test_features_carry_their_id_class_and_program() -> None:
    """sga:featureId, sga:featureClass and sga:featureProgram on each manufacturing feature are its
    p21:id, the class the file's graph types it with and the file's graph."""
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [SLEEVE])
    g = r.graph
    facts = rows(store, g, "SELECT ?f ?n ?c ?p WHERE { ?f sga:featureId ?n ; sga:featureClass ?c ; "
                           "sga:featureProgram ?p } ORDER BY ?f")
    truth = rows(store, g, "SELECT ?f ?n ?c ?p WHERE { ?f a stepnc:manufacturing_feature . GRAPH ?p { ?f p21:id ?n ; "
                           "a ?c } } ORDER BY ?f")
    assert len(facts) >= 5 and facts == truth and {p for *_, p in truth} == {g}


def test_type_names_are_the_local_names_of_the_classes() -> None:
    """sga:operationType and sga:toolBodyType on each step, sga:typeName on each feature and each
    operation (layer version 4) are the local names of the classes the file's graph types the step's
    operation and tool body, the feature and the operation with, read there independently: what the
    library's rows show as operation_type, tool_body and feature_type, once at load instead of per row."""
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [SLEEVE])
    g = r.graph
    on_steps = rows(store, g, "SELECT ?o ?ot ?bt WHERE { ?s sga:order ?o ; sga:operationType ?ot ; "
                              "sga:toolBodyType ?bt } ORDER BY ?o")
    truth = rows(store, g, f"SELECT ?o ?ot ?bt WHERE {{ ?s sga:order ?o ; sga:operation ?op ; sga:tool ?tool . "
                           f"GRAPH <{g}> {{ ?op a ?oc . ?tool stepnc:cutting_tool.its_tool_body ?body . ?body a ?bc }} "
                           "BIND(STRAFTER(STR(?oc), '#') AS ?ot) BIND(STRAFTER(STR(?bc), '#') AS ?bt) } ORDER BY ?o")
    assert len(on_steps) == len(truth) == 13 and on_steps == truth
    named = rows(store, g, "SELECT ?x ?t WHERE { ?x sga:typeName ?t } ORDER BY ?x ?t")
    things = rows(store, g, f"SELECT ?x ?t WHERE {{ {{ ?x a stepnc:manufacturing_feature }} UNION "
                            f"{{ ?x a stepnc:operation }} GRAPH <{g}> {{ ?x a ?c }} "
                            "BIND(STRAFTER(STR(?c), '#') AS ?t) } ORDER BY ?x ?t")
    kinds = {t for _, t in things}
    assert named == things and len(things) >= 18 and {"contouring_rough", "outer_diameter"} <= kinds


def test_a_layer_of_an_older_version_is_written_again_by_the_next_load(tmp_path: Path) -> None:
    """A store whose layer is of the version before (no type names on the steps, features and
    operations) loses the rows of the queries that show them (technology-per-workingstep: every row):
    the query warns, and loading the file again writes the current layer, with the rows of a fresh
    load."""
    from stepnc_graph.loading.derive import LAYER_VERSION

    store = sg.open_store(tmp_path / "store")
    [r] = sg.load(store, [SLEEVE])
    fresh = sg.query(store, "technology-per-workingstep").serialize("csv")
    layer = ox.NamedNode(derived_graph_iri(r.graph))
    new_terms = ("operationType", "toolBodyType", "typeName", "layerVersion")
    for term in new_terms:
        for quad in list(store.oxigraph.quads_for_pattern(None, ox.NamedNode(ANALYSIS_NS + term), None, layer)):
            store.oxigraph.remove(quad)
    store.oxigraph.add(ox.Quad(layer, ox.NamedNode(ANALYSIS_NS + "layerVersion"), ox.Literal(LAYER_VERSION - 1), layer))
    older = sg.query(store, "technology-per-workingstep")
    assert any("from an older stepnc-graph" in w for w in older.warnings) and not older.rows
    [r2] = sg.load(store, [SLEEVE])
    again = sg.query(store, "technology-per-workingstep")
    assert not again.warnings and again.serialize("csv") == fresh and store.count(layer.value) == r2.derived_triples


def test_class_counts_are_the_instances_the_graph_types() -> None:
    from collections import Counter

    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EXAMPLE])
    counts = rows(store, r.graph, "SELECT ?c ?n ?g WHERE { ?x a sga:ClassCount ; sga:countedClass ?c ; "
                                  "sga:instanceCount ?n ; sga:countedIn ?g }")
    typed = Counter(q.object.value for q in store.quads_for_pattern(
        None, ox.NamedNode("http://www.w3.org/1999/02/22-rdf-syntax-ns#type"), None, ox.NamedNode(r.graph))
        if isinstance(q.subject, ox.NamedNode))
    assert {c: int(n) for c, n, _ in counts} == dict(typed) and {g for *_, g in counts} == {r.graph}
    assert typed[STEPNC_NS + "machining_workingstep"] == 8


def test_execution_order_through_every_program_structure() -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [STRUCTURES])
    steps = rows(store, r.graph, "SELECT ?o ?ws ?wp ?setup WHERE { ?s sga:order ?o ; sga:executes ?ws ; "
                                 "sga:workplan ?wp ; sga:setup ?setup } ORDER BY ?o")
    # nested workplan with its own setup; PARALLEL (a SET) in #id order; IF true then false branch;
    # WHILE body once (R30 runs twice); the cycle CYCLE A -> CYCLE B -> CYCLE A entered once; the
    # PROGRAM_STOP is no workingstep; R39 is in no workplan
    assert [(s[1], s[2], s[3]) for s in steps] == [
        ("i30", "i2", "i20"), ("i32", "i3", "i21"), ("i33", "i3", "i21"), ("i34", "i4", "i20"),
        ("i35", "i4", "i20"), ("i36", "i5", "i20"), ("i37", "i7", "i20"), ("i30", "i6", "i20"),
        ("i38", "i8", "i20"), ("i31", "i2", "i20")]
    assert [s[0] for s in steps] == [str(n) for n in range(1, 11)]


def test_without_a_project_every_top_level_structure_is_a_root(tmp_path: Path) -> None:
    text = STRUCTURES.read_text().replace("#1=PROJECT('STRUCTURES',#2,(#10),$,$,$);\n", "")
    path = tmp_path / "no_project.stp"
    path.write_text(text)
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path])
    steps = rows(store, r.graph, "SELECT ?ws WHERE { ?s sga:order ?o ; sga:executes ?ws } ORDER BY ?o")
    # roots in #id order: MAIN (#2) -- CYCLE A/B are contained in each other and in MAIN
    assert [s[0] for s in steps] == ["i30", "i32", "i33", "i34", "i35", "i36", "i37", "i30", "i38", "i31"]


def test_turning_workingstep_features_and_nested_lists(tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [SLEEVE])
    assert rows(store, r.graph, "SELECT ?f WHERE { <%s/i42> sga:feature ?f } ORDER BY ?f" % r.graph) == [
        ("i51",), ("i57",)]
    # its_features is a list: its two cells are indexed 1, 2 (rdf:rest is in the file's graph)
    union = store.query(PREFIXES + "SELECT ?i WHERE { <%s/i42> attr:its_features/<http://www.w3.org/1999/02/"
                                   "22-rdf-syntax-ns#rest>*/sga:index ?i } ORDER BY ?i" % r.graph,
                        use_default_graph_as_union=True)
    assert [int(x["i"].value) for x in union] == [1, 2]


@pytest.mark.parametrize("nested", [False, True])
def test_list_cells_are_read_with_nested_lists(nested: bool) -> None:
    """The derived layer reads the cells along each list, and walks into the members only when one
    is a blank node: a nested list's cells are then found as well (each list indexed from 1)."""
    from stepnc_graph.loading.derive import Lists, Reader

    store = sg.open_store(memory=True)
    inner = "( <http://x/a> <http://x/b> )" if nested else "<http://x/a>"
    store.add_turtle("http://x/g", f"<http://x/s> <http://x/p> ( {inner} <http://x/c> ) .")
    lists = Lists.read(Reader(store, "http://x/g"), ("http://x/p",))
    assert len(lists.first) == (4 if nested else 2)
    heads = {q.object for q in store.quads_for_pattern(None, ox.NamedNode("http://x/p"), None)}
    [head] = heads
    members = lists.members(head)
    assert members[1] == ox.NamedNode("http://x/c")
    if nested:
        assert lists.members(members[0]) == [ox.NamedNode("http://x/a"), ox.NamedNode("http://x/b")]
        indexed = sorted(int(q.object.value) for q in lists.index_quads(ox.NamedNode("http://x/d")))
        assert indexed == [1, 1, 2, 2]


def test_rules_cover_what_the_queries_need() -> None:
    rules = iso14649_rules()
    assert f"{STEPNC_NS}workplan.its_elements" in rules.list_properties
    assert f"{STEPNC_NS}cartesian_point.coordinates" not in rules.list_properties  # geometry: left out
    assert rules.generic[f"{STEPNC_NS}turning_workingstep.its_operation"] == f"{ATTRIBUTE_NS}its_operation"
    assert f"{ANALYSIS_NS}ThreadCuttingTool" in rules.superclasses[f"{STEPNC_NS}tap"]
    assert f"{ANALYSIS_NS}ThreadCuttingTool" in rules.superclasses[f"{STEPNC_NS}tapered_tap"]
    assert "machining_workingstep" in rules.workingsteps and "workplan" in rules.structures


def test_rules_compile_for_any_model(iso_model) -> None:  # type: ignore[no-untyped-def]
    catalog, model = iso_model
    assert compile_rules(model, catalog.naming) == iso14649_rules()


# -- the mapper's part of the layer ----------------------------------------------------------------

PROGRAMS = sorted([EXAMPLE, *FIXTURES.glob("*/*.stp")])
COMPLEX = ("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('c','',(''),(''),'','','');\n"
           "FILE_SCHEMA(('MACHINING_SCHEMA'));\nENDSEC;\nDATA;\n"
           "#1=(AIR_STRATEGY()AP_RETRACT_ANGLE(30.,5.)AP_RETRACT_TANGENT(2.)APPROACH_RETRACT_STRATEGY($));\n"
           "ENDSEC;\n"
           "END-ISO-10303-21;\n")


def _layer_by_construct(store: GraphStore, graph: str) -> set[ox.Quad]:
    """The layer as a CONSTRUCT over the stored graph finds it (the JSON-LD load's way), computed
    in a copy of the file's graph: same blank nodes, so the two layers compare quad by quad."""
    from stepnc_graph.loading.derive import derive

    copy = sg.open_store(memory=True)
    copy.oxigraph.extend(store.quads(graph))
    derive(copy, graph, lambda name: name)
    return set(copy.quads(derived_graph_iri(graph)))


@pytest.mark.parametrize(("kind", "program"), [("memory", p) for p in PROGRAMS] + [("disk", p) for p in (EXAMPLE, SLEEVE, STRUCTURES)],
                         ids=[f"memory-{p.name}" for p in PROGRAMS] + [f"disk-{p.name}" for p in (EXAMPLE, SLEEVE, STRUCTURES)])
def test_the_mapper_writes_what_the_construct_finds(program: Path, kind: str, tmp_path: Path) -> None:
    """The layer a load streams (the mapper's lines, those naming the program's blank nodes in the
    same document as the program's text: list positions, generic values that are lists) is quad
    for quad, blank nodes included, the layer derive() finds by reading the stored graph back
    (the JSON-LD load's way), in memory and through the threaded loader on disk."""
    store = sg.open_store(tmp_path / "store" if kind == "disk" else None, memory=kind == "memory")
    [r] = sg.load(store, [program], lenient=True)
    layer = set(store.quads(derived_graph_iri(r.graph)))
    assert layer == _layer_by_construct(store, r.graph)
    assert len(layer) == r.derived_triples
    store.close()


@pytest.mark.parametrize("program", PROGRAMS, ids=[p.name for p in PROGRAMS])
def test_the_mappers_blank_node_lines_are_what_derive_writes_as_quads(program: Path) -> None:
    """The layer's lines with the program's blank nodes (list positions, generic values that are
    blank nodes), which the mapper writes with the program's text (Joint chunks), are the quads
    derive() finds by reading the graph back: the program's text read with its blank node labels
    kept, derive's queries over it give the same triples."""
    from stepnc_graph.loading.derive import Lists, Reader
    from stepnc_graph.loading.loader import _Load
    from stepnc_graph.store import Joint

    job = _Load.of_file(program, True, None, None)
    chunks = list(job.chunks())
    graph = ox.NamedNode(job.graph)
    store = ox.Store()
    text = "".join(c.text if isinstance(c, Joint) else c for c in chunks if isinstance(c, str | Joint)).encode()
    store.extend(ox.Quad(t.subject, t.predicate, t.object, graph) for t in ox.parse(text, ox.RdfFormat.N_TRIPLES))
    rules, reader = iso14649_rules(), Reader(store, job.graph)  # type: ignore[arg-type]
    expected = {(q.subject, q.predicate, q.object) for q in Lists.read(reader, rules.list_properties).index_quads(graph)}
    expected |= {(s, p, o) for s, p, o in reader.select(rules.blank_values)}
    joint = "".join(c.lines for c in chunks if isinstance(c, Joint))
    written = [(t.subject, t.predicate, t.object) for t in ox.parse(joint.encode(), ox.RdfFormat.N_TRIPLES)]
    assert set(written) == expected and len(written) == len(expected) == job.blank_written
    if program in (EXAMPLE, SLEEVE):
        assert any(p.value == ANALYSIS_NS + "index" for _, p, _ in written)


def test_a_complex_instance_gets_each_superclass_once(tmp_path: Path) -> None:
    program = tmp_path / "complex.stp"
    program.write_text(COMPLEX)
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program])
    layer = set(store.quads(derived_graph_iri(r.graph)))
    assert layer == _layer_by_construct(store, r.graph)
    assert len(layer) == r.derived_triples
    types = rows(store, r.graph, "SELECT ?c WHERE { <%s/i1> a ?c }" % r.graph)
    assert types and len(types) == len(set(types))


# -- round trip, replace, unload ------------------------------------------------------------------


def test_the_writer_ignores_the_derived_layer(tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [SLEEVE])
    with_layer = sg.export(store, "p21", r.graph)
    store.oxigraph.remove_graph(ox.NamedNode(derived_graph_iri(r.graph)))
    assert sg.export(store, "p21", r.graph) == with_layer
    again = tmp_path / "sleeve_two_setups.stp"
    again.write_bytes(with_layer)
    [r2] = sg.load(store, [again], replace=True)  # the exported program gives the same derived layer
    assert r2.derived_triples == r.derived_triples
    assert store.count(derived_graph_iri(r.graph)) == r.derived_triples


@pytest.mark.parametrize("memory", [False, True], ids=["disk", "memory"])
def test_reload_replaces_and_unload_removes_the_layer(tmp_path: Path, memory: bool) -> None:
    store = sg.open_store(None if memory else tmp_path / "store", memory=memory)
    path = tmp_path / "shaft.stp"
    path.write_text(EXAMPLE.read_text())
    [r] = sg.load(store, [path])
    layer = derived_graph_iri(r.graph)
    assert store.count(layer) == r.derived_triples > 400
    # a new version with one workingstep less: no step of the old layer survives
    path.write_text(EXAMPLE.read_text().replace("#3=WORKPLAN('SETUP 1 - RIGHT END',(#30,#31,#32,#33,#34)",
                                                "#3=WORKPLAN('SETUP 1 - RIGHT END',(#30,#31,#32,#33)"))
    [r2] = sg.load(store, [path])
    assert store.count(layer) == r2.derived_triples
    assert rows(store, r.graph, "SELECT (MAX(?o) AS ?n) WHERE { ?s sga:order ?o }") == [("7",)]
    assert listed_graphs(store) == [r.graph]
    assert sg.unload(store, r.graph) is True
    assert store.count(layer) == 0 and listed_graphs(store) == []
    # on disk the vocabulary stays; a throw-away store gets it only when queried
    assert (stored_digest(store) is None) == memory


@pytest.mark.parametrize("memory", [False, True], ids=["disk", "memory"])
def test_a_failing_derivation_rolls_the_whole_load_back(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        memory: bool) -> None:
    store = sg.open_store(None if memory else tmp_path / "store", memory=memory)
    sg.load(store, [EXAMPLE])
    before = sorted(str(q) for q in store.quads())
    loader = sys.modules["stepnc_graph.loading.loader"]
    real = loader.derive

    def failing(*args, **kwargs):  # type: ignore[no-untyped-def]
        real(*args, **kwargs)  # the layer is written, then the load fails
        raise RuntimeError("injected after the derived layer")

    monkeypatch.setattr(loader, "derive", failing)
    with pytest.raises(RuntimeError, match="injected"):
        sg.load(store, [EXAMPLE])
    assert sorted(str(q) for q in store.quads()) == before


def test_reserved_graph_names_are_refused(tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EXAMPLE])
    with pytest.raises(ValueError, match="reserved"):
        sg.load(store, [EXAMPLE], base_iri=VOCABULARY_GRAPH)
    with pytest.raises(ValueError, match="reserved"):
        sg.load(store, [EXAMPLE], base_iri=derived_graph_iri(r.graph))


# -- the vocabulary graph --------------------------------------------------------------------------


def test_vocabulary_graph_answers_subclass_questions(example: tuple[GraphStore, str]) -> None:
    store, g = example
    assert vocabulary_status(store) == "current"
    # any turning tool body, through rdfs:subClassOf* in the vocabulary graph, over the file's graph
    # alone (0 without the vocabulary)
    query = PREFIXES + ("SELECT (COUNT(?b) AS ?n) WHERE { ?t stepnc:cutting_tool.its_tool_body ?b . "
                        "?b a/rdfs:subClassOf* stepnc:turning_machine_tool_body }")
    found = store.query(query, default_graph=[ox.NamedNode(g), ox.NamedNode(VOCABULARY_GRAPH)])
    assert int(next(iter(found))["n"].value) == 2
    assert int(next(iter(store.query(query, default_graph=[ox.NamedNode(g)])))["n"].value) == 0
    # the derived closure says the same in one triple pattern
    found = store.query(PREFIXES + "SELECT (COUNT(?b) AS ?n) WHERE { ?t stepnc:cutting_tool.its_tool_body ?b . "
                                   "?b a stepnc:turning_machine_tool_body }", use_default_graph_as_union=True)
    assert int(next(iter(found))["n"].value) == 2
    subs = store.query(PREFIXES + f"SELECT ?p WHERE {{ GRAPH <{VOCABULARY_GRAPH}> {{ ?p rdfs:subPropertyOf "
                                  "attr:its_id } } ORDER BY ?p")
    assert len(list(subs)) == 9


def test_stale_or_missing_vocabulary_is_rewritten_by_the_next_load(tmp_path: Path) -> None:
    store = sg.open_store(tmp_path / "store")
    assert vocabulary_status(store) == "missing"
    sg.load(store, [EXAMPLE])
    digest = vocabulary_digest()
    size = store.count(VOCABULARY_GRAPH)
    assert stored_digest(store) == digest
    assert size == 1 + sum(len(list(ox.parse(path=str(p), format=ox.RdfFormat.TURTLE))) for p in vocabulary_files())
    node = ox.NamedNode(VOCABULARY_GRAPH)
    store.oxigraph.remove(ox.Quad(node, ox.NamedNode(DIGEST), ox.Literal(digest), node))
    store.oxigraph.add(ox.Quad(node, ox.NamedNode(DIGEST), ox.Literal("0" * 64), node))
    store.oxigraph.add(ox.Quad(node, node, node, node))  # something an old vocabulary had
    assert vocabulary_status(store) == "stale"
    sg.load(store, [STRUCTURES])
    assert vocabulary_status(store) == "current" and store.count(VOCABULARY_GRAPH) == size


def test_whole_store_nquads_hold_the_files_graphs_and_a_layer_when_named(tmp_path: Path) -> None:
    store = sg.open_store(tmp_path / "store")
    [r] = sg.load(store, [EXAMPLE])
    data = sg.export(store, "nq").decode()
    graphs = {line.rsplit(" ", 2)[-2] for line in data.splitlines() if line}
    assert graphs == {f"<{r.graph}>"}  # the derived layer and the vocabulary are written again by a load
    for layer in (derived_graph_iri(r.graph), VOCABULARY_GRAPH):  # each exported when named
        named = sg.export(store, "nq", layer).decode()
        assert named and {line.rsplit(" ", 2)[-2] for line in named.splitlines() if line} == {f"<{layer}>"}
    one = sg.export(store, "nt", r.graph).decode()
    assert "analysis#" not in one and "owl#Class" not in one  # a file's export: its graph only


@pytest.mark.parametrize("program", [EXAMPLE, FIXTURES / "p21" / "fail_seed_annex_d.stp"], ids=["example", "lenient"])
def test_a_load_without_the_layer_writes_the_same_program_graph(program: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """What ``validate FILE`` does: its throw-away store needs the program graph only."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")  # the two loads' timestamps are equal
    with_layer, without = sg.open_store(memory=True), sg.open_store(memory=True)
    [r] = sg.load(with_layer, [program], lenient=True)
    [r2] = sg.load(without, [program], lenient=True, derived=False)
    assert r2.derived_triples == 0 and not without.oxigraph.contains_named_graph(ox.NamedNode(derived_graph_iri(r.graph)))
    def named(store: GraphStore) -> set[ox.Quad]:  # blank node labels differ between two loads
        return {q for q in store.quads(r.graph) if not isinstance(q.subject, ox.BlankNode)
                and not isinstance(q.object, ox.BlankNode)}

    assert named(without) == named(with_layer) and without.count(r.graph) == with_layer.count(r.graph)
    assert r2.triples == r.triples and [d.code for d in r2.diagnostics] == [d.code for d in r.diagnostics]


def test_a_layer_written_in_pieces_is_the_layer_written_whole(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The layer's text goes to the store in pieces and its blank-node quads in bounded calls (so a
    program of 1M instances does not hold them all): cut small here, the program and its layer are
    the same graphs as one cut large, blank nodes shared between the two included."""
    import rdflib
    from rdflib.compare import isomorphic

    from stepnc_graph.loading import derive as derive_module
    from stepnc_graph.store import tuning

    RDF_TYPE = "http://www.w3.org/1999/02/22-rdf-syntax-ns#type"

    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")  # the two loads' timestamps are equal

    def loaded(name: str) -> tuple[rdflib.Graph, int]:
        with sg.open_store(tmp_path / name) as store:
            [r] = sg.load(store, [EXAMPLE])
            both = rdflib.Graph()  # the program and its layer in one graph: shared nodes stay shared
            for graph, mark in ((r.graph, ""), (derived_graph_iri(r.graph), "-derived")):
                for t in rdflib.Graph().parse(data=sg.export(store, "nt", graph).decode(), format="nt"):
                    both.add((t[0], rdflib.URIRef(str(t[1]) + mark), t[2]))
            return both, r.derived_triples

    whole, whole_count = loaded("whole")
    monkeypatch.setattr(derive_module, "TEXT_PIECE", 300)
    monkeypatch.setattr(tuning, "TRANSACTION_QUADS", 3)
    monkeypatch.setattr(tuning, "INSERT_BATCH", 5)
    pieces, pieces_count = loaded("pieces")
    layer_of = rdflib.URIRef(ANALYSIS_NS + "layerOf-derived")
    step = rdflib.URIRef(ANALYSIS_NS + "ExecutionStep")
    for layer in (whole, pieces):  # the last line written, and every step of the order (see the order test)
        assert len(list(layer.triples((None, layer_of, None)))) == 1
        assert len(list(layer.triples((None, rdflib.URIRef(RDF_TYPE + "-derived"), step)))) == 8
    assert pieces_count == whole_count and len(pieces) == len(whole)
    assert any(isinstance(s, rdflib.BNode) for s, p, _ in pieces if str(p).endswith("index-derived"))
    assert isomorphic(pieces, whole)
