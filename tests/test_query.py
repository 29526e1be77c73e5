"""The query library and the query API: exact rows, parameters as terms, errors, result formats.

Expected rows of every library query on the shipped example, the corrected seed programs and the
query fixtures are in ``tests/fixtures/query/expected/<query>.csv`` (SPARQL 1.1 CSV). They were
checked by hand against the programs (the independent checks below recompute some of them); after
an intended change, regenerate with ``STEPNC_GRAPH_UPDATE_EXPECTED=1 python -m pytest
tests/test_query.py -k expected`` and review the diff.
"""

from __future__ import annotations

import csv
import importlib
import io
import json
import os
from collections import Counter
from pathlib import Path

import pyoxigraph as ox
import pytest

import stepnc_graph as sg
from stepnc_graph.loading.derive import iso14649_rules
from stepnc_graph.core.naming import DATA_BASE, STEPNC_NS, VOCABULARY_GRAPH
from stepnc_graph.part21 import read_file
from stepnc_graph.querying.query import QueryError, library, parse_header, resolve
from stepnc_graph.core.resources import queries_dir
from stepnc_graph.store import GraphStore
from stepnc_graph.core.naming import listed_graphs

from conftest import FIXTURES, ROOT

PROGRAMS = ["examples/shaft_two_setups.stp", "tests/fixtures/p21/pass_seed_annex_d.stp",
            "tests/fixtures/p21/pass_seed_annex_e.stp", "tests/fixtures/query/sleeve_two_setups.stp",
            "tests/fixtures/query/structures.stp"]
EXPECTED = FIXTURES / "query" / "expected"
NAMES = sorted(p.stem for p in queries_dir().glob("*.rq"))
SHAFT = DATA_BASE + "shaft_two_setups.stp"
SLEEVE = DATA_BASE + "sleeve_two_setups.stp"


@pytest.fixture(scope="module")
def store() -> GraphStore:
    cwd = os.getcwd()
    os.chdir(ROOT)  # dcterms:source records the path as given: keep it relative and stable
    try:
        s = sg.open_store(memory=True)
        sg.load(s, PROGRAMS)
    finally:
        os.chdir(cwd)
    return s


def csv_rows(data: bytes) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(data.decode("utf-8"), newline="")))


# -- exact rows ------------------------------------------------------------------------------------


def test_the_library_has_the_stable_names() -> None:
    assert {"workingsteps-by-tool-type", "setup-sheet", "workplan-sequence", "operations-per-feature",
            "features-without-operations", "roughed-not-finished", "technology-per-workingstep",
            "tool-changes", "instance-counts"} <= set(NAMES)
    assert len(NAMES) >= 15


@pytest.mark.parametrize("name", NAMES)
def test_expected_rows(name: str, store: GraphStore) -> None:
    data = sg.query(store, name).serialize("csv").decode("utf-8").replace("\r\n", "\n")  # CSV ends lines CRLF
    data = data.replace(f"{ROOT}/", "")  # source paths are absolute: the expected rows are of any checkout
    path = EXPECTED / f"{name}.csv"
    if os.environ.get("STEPNC_GRAPH_UPDATE_EXPECTED"):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(data, encoding="utf-8")
    assert data == path.read_text(encoding="utf-8"), f"rows of {name} changed"


@pytest.mark.parametrize("name", NAMES)
def test_one_graph_gives_that_programs_rows(name: str, store: GraphStore) -> None:
    everything = csv_rows(sg.query(store, name).serialize("csv"))
    for graph in (SHAFT, SLEEVE):
        one = csv_rows(sg.query(store, name, graph=graph).serialize("csv"))
        assert one == [r for r in everything if r["program"] == graph]


@pytest.mark.parametrize("name", NAMES)
def test_rows_naming_a_thing_give_its_id_and_ref(name: str, store: GraphStore) -> None:
    result = sg.query(store, name)
    columns = result.variables
    assert columns[0] == "program"
    for thing in ("workingstep", "feature", "tool", "finish", "rough", "from_tool", "to_tool"):
        if thing in columns:
            assert f"{thing}_ref" in columns, (name, thing)
            for row in result:
                if row[thing] is not None or row.get(f"{thing}_ref") is not None:
                    assert str(row[f"{thing}_ref"]).startswith("#"), (name, row)


@pytest.mark.parametrize("name", NAMES)
def test_queries_judged_vocabulary_free_give_the_same_rows_without_it(name: str, store: GraphStore) -> None:
    """A throw-away store gets the vocabulary graph only for queries that may read it
    (Query.needs_vocabulary): for every other library query the rows must not depend on it."""
    from stepnc_graph.querying.query import execute
    from stepnc_graph.graphs.vocabulary_graph import ensure_vocabulary, is_throwaway

    query = resolve(name)
    assert query.library and is_throwaway(store)
    if query.needs_vocabulary:
        pytest.skip(f"{name} gets the vocabulary graph")
    bare = sg.open_store(memory=True)
    bare.oxigraph.extend(q for q in store.oxigraph.quads_for_pattern(None, None, None, None)
                         if q.graph_name != ox.NamedNode(VOCABULARY_GRAPH))
    without = execute(bare, query).serialize("csv")
    assert bare.count(VOCABULARY_GRAPH) == 0 and not execute(bare, query).warnings
    ensure_vocabulary(store)
    assert execute(store, query).serialize("csv") == without


@pytest.fixture(scope="module")
def linked_store(store: GraphStore) -> GraphStore:
    """The programs, their derived layers, the vocabulary and a PLM link graph: every kind of graph."""
    from stepnc_graph.graphs.vocabulary_graph import ensure_vocabulary

    s = sg.open_store(memory=True)
    s.oxigraph.extend(store.oxigraph.quads_for_pattern(None, None, None, None))
    ensure_vocabulary(s)
    sg.link(s, ROOT / "examples" / "shaft_plm_links.csv", SHAFT)
    return s


@pytest.mark.parametrize("name", NAMES)
def test_library_queries_need_no_list_of_named_graphs(name: str, linked_store: GraphStore,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """Library queries over the whole store run with the store's own named graphs (query.dataset: a
    GRAPH pattern over a list of graphs costs a look-up per graph and row); their rows must be those
    of the documented dataset, where GRAPH ?program reaches the files' graphs only -- also beside
    derived layers, the vocabulary and a link graph."""
    q = importlib.import_module("stepnc_graph.querying.query")  # the module: sg.query is the function
    own = sg.query(linked_store, name).serialize("json")
    listed = q.dataset
    monkeypatch.setattr(q, "dataset", lambda store, graph, library=False, vocabulary=False:
                        listed(store, graph, vocabulary=vocabulary))
    assert sg.query(linked_store, name).serialize("json") == own


def test_the_library_gets_the_stores_own_named_graphs(store: GraphStore) -> None:
    from stepnc_graph.querying.query import dataset

    assert dataset(store, None, library=True) == {"use_default_graph_as_union": True}
    assert [g.value for g in dataset(store, None)["named_graphs"]] == listed_graphs(store)  # other queries: files only
    # one program: its graph, and for the library the vocabulary graph too (GRAPH <vocabulary>: one
    # look-up per path step there, not one in each of the default graph's three graphs)
    assert [g.value for g in dataset(store, SHAFT)["named_graphs"]] == [SHAFT]
    assert [g.value for g in dataset(store, SHAFT, library=True)["named_graphs"]] == [SHAFT, VOCABULARY_GRAPH]
    assert dataset(store, SHAFT, library=True)["default_graph"] == dataset(store, SHAFT)["default_graph"]


@pytest.mark.parametrize("name", NAMES)
def test_library_rows_with_graph_ignore_the_vocabulary_as_a_named_graph(name: str, linked_store: GraphStore,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """With --graph a library query's named graphs are the program's and the vocabulary's; a query
    that does not name the vocabulary graph must give the rows it gives with the program's alone
    (a GRAPH ?g of the library reaches files' graphs only)."""
    query = resolve(name)
    if f"<{VOCABULARY_GRAPH}>" in query.text:
        pytest.skip(f"{name} reads the vocabulary graph by name")
    q = importlib.import_module("stepnc_graph.querying.query")
    own = sg.query(linked_store, name, graph=SHAFT).serialize("json")
    listed = q.dataset
    monkeypatch.setattr(q, "dataset", lambda store, graph, library=False, vocabulary=False:
                        listed(store, graph, vocabulary=vocabulary))
    assert sg.query(linked_store, name, graph=SHAFT).serialize("json") == own


def test_instance_counts_of_one_program_are_its_rows_of_the_whole_store(linked_store: GraphStore) -> None:
    """instance-counts reads superclasses in the vocabulary graph by name: with --graph (the
    vocabulary a named graph of the dataset) it must give the program's rows of the whole store."""
    whole = [r for r in sg.query(linked_store, "instance-counts").rows if r["program"] == SHAFT]
    assert len(whole) > 20 and {"workingstep", "RoughingOperation"} <= {r["class"] for r in whole}
    assert sg.query(linked_store, "instance-counts", graph=SHAFT).rows == whole


def test_a_query_naming_the_vocabulary_graph_reaches_it(linked_store: GraphStore, tmp_path: Path) -> None:
    """The library's instance-counts reads GRAPH <vocabulary>: the same text run as your own query
    (whose named graphs are the files' otherwise) gives the library's rows, whole store and --graph."""
    mine = tmp_path / "counts.rq"
    mine.write_text(resolve("instance-counts").text)
    assert not resolve(str(mine)).library
    for graph in (None, SHAFT):
        rows = sg.query(linked_store, str(mine), graph=graph).rows
        assert rows and rows == sg.query(linked_store, "instance-counts", graph=graph).rows


def test_user_queries_always_get_the_vocabulary(tmp_path: Path) -> None:
    text = "SELECT ?p WHERE { <https://w3id.org/stepnc-graph/iso14649#turning_workingstep> ?p ?o } LIMIT 1"
    rq = tmp_path / "mine.rq"
    rq.write_text(text)
    assert resolve(text).needs_vocabulary and resolve(str(rq)).needs_vocabulary
    with sg.open_store(memory=True) as s:
        sg.load(s, [ROOT / "examples" / "shaft_two_setups.stp"])
        assert sg.query(s, text).rows  # the class is described in the vocabulary graph only


def test_library_headers_are_complete() -> None:
    for q in library():
        assert q.title and q.description and q.examples, q.name
        ox.Store().query(q.text)  # self-contained: parses without the predeclared prefixes
        for p in q.params:
            assert f"?{p.name}" in q.text.split("WHERE")[0], f"{q.name}: parameter {p.name} must be selected"


# -- independent checks of some answers -------------------------------------------------------------


def test_grooving_tools_answer_the_mission_question(store: GraphStore) -> None:
    rows = sg.query(store, "workingsteps-by-tool-type", graph=SHAFT).rows
    assert [(r["workingstep"], r["workingstep_ref"], r["tool"], r["tool_ref"], r["setup"]) for r in rows] == [
        ("WS5 RELIEF GROOVE", "#34", "T02 GROOVING 3MM", "#110", "SETUP 1")]
    threads = sg.query(store, "workingsteps-by-tool-type", graph=SLEEVE, tool_type="sga:ThreadCuttingTool").rows
    assert [r["workingstep"] for r in threads] == ["WS07 THREAD ROUGH", "WS08 THREAD FINISH"]
    bodies = sg.query(store, "workingsteps-by-tool-type", graph=SLEEVE, tool_type="tool_body")
    # every workingstep of the sleeve has a cutting tool with a body; WS13 machines two features
    assert len(bodies) == 14 and len(set(bodies.column("workingstep_ref"))) == 13


def _tool_changes_by_hand(path: Path) -> list[int]:
    """Orders of the tool changes, from the Part 21 instances alone (in these files the main
    workplan lists one workplan per setup, each a flat list of machining workingsteps)."""
    inst = {i.id: i for i in read_file(path).instances()}
    # MACHINING_WORKINGSTEP(its_id, its_secplane, its_feature, its_operation, its_effect); its_tool is
    # the 6th parameter of a turning operation
    tool_of = {i.id: int(inst[int(i.params[3])].params[5]) for i in inst.values() if i.name == "MACHINING_WORKINGSTEP"}
    main = next(i for i in inst.values() if i.name == "PROJECT").params[1]
    order = [int(ws) for wp in inst[int(main)].params[1] for ws in inst[int(wp)].params[1]]
    return [n + 1 for n in range(1, len(order)) if tool_of[order[n]] != tool_of[order[n - 1]]]


def test_tool_changes_agree_with_a_count_by_hand(store: GraphStore) -> None:
    rows = sg.query(store, "tool-changes", graph=SHAFT).rows
    assert [r["order"] for r in rows] == _tool_changes_by_hand(ROOT / PROGRAMS[0]) == [5, 6]
    assert {r["changes"] for r in rows} == {2}
    zero = sg.query(store, "tool-changes", graph=DATA_BASE + "pass_seed_annex_d.stp").rows
    assert [(r["changes"], r["order"]) for r in zero] == [(0, None)]


def test_instance_counts_agree_with_the_part21_file(store: GraphStore, iso_model) -> None:  # type: ignore[no-untyped-def]
    _, model = iso_model
    direct: Counter[str] = Counter(str(i.name).lower() for i in read_file(ROOT / PROGRAMS[2]).instances())
    rolled: Counter[str] = Counter()
    for entity, n in direct.items():
        for cls in (entity, *model.ancestors(entity)):
            rolled[cls] += n
    rules = iso14649_rules()
    for entity, n in direct.items():
        for sup in rules.superclasses.get(STEPNC_NS + entity, ()):
            if "#" in sup and not sup.startswith(STEPNC_NS):
                rolled[sup.rsplit("#", 1)[1]] += n
    rows = sg.query(store, "instance-counts", graph=DATA_BASE + "pass_seed_annex_e.stp").rows
    assert {r["class"]: r["including_subtypes"] for r in rows} == dict(rolled)
    assert {r["class"]: r["instances"] for r in rows if r["instances"]} == dict(direct)


def test_precedence_and_planning_gaps(store: GraphStore) -> None:
    assert [(r["feature"], r["finish"], r["rough"]) for r in sg.query(store, "finish-before-rough").rows] == [
        ("OD 40", "WS11 OD40 FINISH", "WS12 OD40 ROUGH")]
    assert [(r["program"], r["feature"]) for r in sg.query(store, "roughed-not-finished").rows] == [
        (SHAFT, "RELIEF GROOVE"), (SLEEVE, "RELIEF")]
    assert [r["feature"] for r in sg.query(store, "features-without-operations").rows] == ["SPARE GROOVE"]
    assert [r["workingstep"] for r in sg.query(store, "workingsteps-not-in-plan").rows] == ["R39 UNUSED"]


# -- parameters ------------------------------------------------------------------------------------


def test_parameters_are_bound_as_terms_not_text(store: GraphStore, tmp_path: Path) -> None:
    rq = tmp_path / "echo.rq"
    rq.write_text("# title: echo\n# param: text (string) -- any text\n# param: n (integer) = 3\n"
                  "SELECT ?text ?n ?len WHERE { BIND(STRLEN(?text) AS ?len) }\n")
    hostile = '" } ; DROP ALL ; SELECT * WHERE { "'
    [row] = sg.query(store, str(rq), text=hostile).rows
    assert row == {"text": hostile, "n": 3, "len": len(hostile)}
    assert sg.query(store, str(rq), text="x", n="-12").rows[0]["n"] == -12
    with pytest.raises(QueryError, match="expected an integer") as bad:
        sg.query(store, str(rq), text="x", n="3; DROP")
    assert bad.value.parameter == "n" and bad.value.line == 3 and bad.value.source == str(rq)
    with pytest.raises(QueryError, match="required"):
        sg.query(store, str(rq))
    with pytest.raises(QueryError, match="unknown parameter 'colour'; echo takes text, n"):
        sg.query(store, str(rq), text="x", colour="red")


def test_class_parameter_is_checked_against_the_vocabulary(store: GraphStore) -> None:
    with pytest.raises(QueryError, match="no class 'grooving_tol'.*did you mean grooving_tool") as bad:
        sg.query(store, "workingsteps-by-tool-type", tool_type="grooving_tol")
    assert bad.value.line is not None and bad.value.source.endswith("workingsteps-by-tool-type.rq")
    with pytest.raises(QueryError, match="Invalid IRI"):  # not a class name, and never query text
        sg.query(store, "workingsteps-by-tool-type", tool_type="grooving_tool> } UNION { ?s ?p ?o")
    iri = sg.query(store, "workingsteps-by-tool-type", tool_type=f"<{STEPNC_NS}grooving_tool>")
    assert len(iri) == len(sg.query(store, "workingsteps-by-tool-type"))


def test_a_known_class_parameter_is_one_look_up(store: GraphStore, monkeypatch: pytest.MonkeyPatch) -> None:
    """A class the vocabulary has is checked with an ASK: listing the vocabulary's classes (each IRI
    read from the string table, 7-11 ms on a 100k store) is for suggesting names for an unknown one."""
    from stepnc_graph.graphs.vocabulary_graph import ensure_vocabulary
    from stepnc_graph.querying.query import to_term

    ensure_vocabulary(store)  # a throw-away store gets it with its first query that reads it
    asked: list[str] = []
    real = store.query
    monkeypatch.setattr(store, "query", lambda text, **kw: asked.append(text) or real(text, **kw))
    assert to_term(store, "class", "grooving_tool") == ox.NamedNode(STEPNC_NS + "grooving_tool")
    assert to_term(store, "class", "sga:ThreadCuttingTool").value.endswith("analysis#ThreadCuttingTool")
    assert len(asked) == 2 and all(text.startswith("ASK") for text in asked)
    with pytest.raises(ValueError, match="did you mean grooving_tool"):
        to_term(store, "class", "grooving_tol")


def test_undeclared_parameters_of_inline_queries(store: GraphStore) -> None:
    q = "SELECT ?ws ?label WHERE { ?ws attr:its_id ?label ; a stepnc:workingstep }"
    assert [r["ws"] for r in sg.query(store, q, label="WS5 RELIEF GROOVE")] == [f"{SHAFT}/i34"]
    with pytest.raises(QueryError, match="must SELECT \\?missing"):
        sg.query(store, "SELECT ?ws WHERE { ?ws attr:its_id ?missing }", missing="x")


def test_header_parsing_and_malformed_declarations() -> None:
    header = parse_header("# title: T\n# description: first\n#   second\n# param: a (decimal) = 1.5 -- doc\n"
                          "SELECT ?a WHERE {}", "x.rq")
    assert header["description"] == "first second"
    [p] = header["params"]
    assert (p.name, p.type, p.default, p.doc, p.line) == ("a", "decimal", "1.5", "doc", 4)
    with pytest.raises(QueryError, match="malformed parameter") as bad:
        parse_header("# title: T\n# param: a (colour)\nSELECT ?a {}", "x.rq")
    assert (bad.value.source, bad.value.line) == ("x.rq", 2)


# -- errors, read-only, formats --------------------------------------------------------------------


def test_syntax_errors_are_positioned(store: GraphStore) -> None:
    text = "SELECT ?x WHERE {\n  ?x a stepnc:workingstep ;\n     attr:its_id ?id ?\n}"
    with pytest.raises(QueryError) as bad:
        sg.query(store, text)
    assert (bad.value.source, bad.value.line, bad.value.column) == ("-e", 3, 22)  # the ? without a name
    assert "-e:3:22" in str(bad.value) and "^" in str(bad.value) and "without a name" in str(bad.value)
    with pytest.raises(QueryError, match="prefix is not declared"):
        sg.query(store, "SELECT ?x WHERE { ?x a nope:thing }")


def test_unknown_names_and_graphs(store: GraphStore) -> None:
    with pytest.raises(QueryError, match="did you mean tool-changes"):
        resolve("tool-change")
    with pytest.raises(QueryError, match="no loaded file with graph"):
        sg.query(store, "tool-changes", graph="https://example.org/nothing")
    with pytest.raises(QueryError, match="no query file"):
        resolve("missing.rq")


def test_queries_are_read_only(store: GraphStore) -> None:
    before = len(store.oxigraph)
    for update in ("INSERT DATA { <urn:a> <urn:b> <urn:c> }", "DROP ALL", "CLEAR GRAPH <%s>" % SHAFT):
        with pytest.raises(QueryError, match="updates are not allowed, queries are read-only"):
            sg.query(store, update)
    assert len(store.oxigraph) == before


def test_ask_and_construct(store: GraphStore) -> None:
    ask = sg.query(store, "ASK { ?op a sga:RoughingOperation }")
    assert ask.kind == "ask" and ask.boolean is True
    assert json.loads(ask.serialize("json")) == {"head": {}, "boolean": True}
    graph = sg.query(store, "CONSTRUCT { ?ws rdfs:label ?l } WHERE { ?ws a stepnc:workingstep ; rdfs:label ?l }",
                     graph=SHAFT)
    assert graph.kind == "graph" and len(graph) == 8
    assert graph.serialize("table").count(b"\n") == 8


def test_result_formats_are_the_standard_ones(store: GraphStore) -> None:
    result = sg.query(store, "setup-sheet", graph=SHAFT)
    assert result._terms is None  # the JSON formats need no Python terms: parsed on first use
    for fmt, kind in (("json", ox.QueryResultsFormat.JSON), ("tsv", ox.QueryResultsFormat.TSV)):
        parsed = ox.parse_query_results(result.serialize(fmt), format=kind)
        assert isinstance(parsed, ox.QuerySolutions)
        assert [v.value for v in parsed.variables] == result.variables
        assert [tuple(row) for row in parsed] == result.terms
    table = csv_rows(result.serialize("csv"))  # CSV is lossy by design: plain values (SPARQL 1.1 CSV)
    assert list(table[0]) == result.variables and len(table) == len(result) == 3
    assert table[0]["tool"] == "T01 CNMG 120408" and table[0]["program"] == SHAFT
    doc = json.loads(result.serialize("json"))
    assert doc["head"]["vars"][0] == "program" and doc["results"]["bindings"][0]["uses"] == {
        "type": "literal", "value": "4", "datatype": "http://www.w3.org/2001/XMLSchema#integer"}
    md = result.serialize("md").decode().splitlines()
    assert md[0].startswith("| program | setup |") and md[1].startswith("|---|") and len(md) == 5
    table = result.serialize("table").decode().splitlines()
    assert table[0].split()[:3] == ["program", "setup", "tool"] and "data:shaft_two_setups.stp" in table[1]
    rows = result.rows
    assert rows[0]["uses"] == 4 and isinstance(rows[0]["nose_radius"], float)


def test_dataframe_when_pandas_is_installed(store: GraphStore) -> None:
    pd = pytest.importorskip("pandas")
    frame = sg.query(store, "tool-usage", graph=SHAFT).to_dataframe()
    assert isinstance(frame, pd.DataFrame) and list(frame["workingsteps"]) == [7, 1]


def test_warnings_for_a_store_without_vocabulary_or_layer(tmp_path: Path) -> None:
    s = sg.open_store(tmp_path / "store")  # on disk: a throw-away store would get the vocabulary back
    [r] = sg.load(s, [ROOT / PROGRAMS[0]])
    s.oxigraph.remove_graph(ox.NamedNode(r.graph + "/derived"))
    s.oxigraph.remove_graph(ox.NamedNode("https://w3id.org/stepnc-graph/iso14649"))
    result = sg.query(s, "tool-changes")
    assert any("vocabulary graph is missing" in w for w in result.warnings)
    assert any("no derived layer" in w for w in result.warnings)


def test_warning_for_a_layer_of_an_older_version(tmp_path: Path) -> None:
    """A layer written before the steps carried their program (LAYER_VERSION 2) leaves the
    row-per-step queries without those programs' rows: the query says so."""
    from stepnc_graph.core.naming import ANALYSIS_NS

    s = sg.open_store(tmp_path / "store")
    [r] = sg.load(s, [ROOT / PROGRAMS[0]])
    assert not sg.query(s, "tool-changes").warnings
    layer = ox.NamedNode(r.graph + "/derived")
    s.oxigraph.remove_graph(layer)
    s.oxigraph.add(ox.Quad(layer, ox.NamedNode(ANALYSIS_NS + "layerOf"), ox.NamedNode(r.graph), layer))
    assert any("from an older stepnc-graph" in w for w in sg.query(s, "tool-changes").warnings)
    assert any("from an older stepnc-graph" in w for w in sg.query(s, "tool-changes", graph=r.graph).warnings)


def test_html_reference_helps_an_analyst() -> None:
    html = (ROOT / "docs" / "ontology.html").read_text(encoding="utf-8")
    for name in NAMES:  # every library query is listed as an example
        assert f"<code>{name}</code>" in html
    assert 'id="index"' in html and 'id="az-w"' in html and 'id="core"' in html
    section = html[html.index('id="machining_workingstep"'):]
    section = section[:section.index("</section>")]
    assert "its_id (executable)" in section and "<code>attr:its_operation</code>" in section
    assert '<a href="#machining_operation"><code>machining_operation</code></a>' in section  # type linked
    used = html[html.index('id="setup"'):]
    assert "Used by" in used[:used.index("</section>")] and "workplan</code></a>.<code>its_setup" in used


def test_program_summary_names_the_project_with_the_smallest_id(tmp_path: Path) -> None:
    """A program holding several projects is summarised by the one with the smallest #id: one
    project looked up per program (not each copy's), the same answer on every store -- not
    whichever one the store's SAMPLE picks."""
    text = (ROOT / "examples" / "shaft_two_setups.stp").read_text().replace(
        "#1=PROJECT('SHAFT-42',", "#1=PROJECT('FIRST PROJECT',#2,(#10),$,$,$);\n#9001=PROJECT('SHAFT-42',")
    path = tmp_path / "two_projects.stp"
    path.write_text(text)
    store = sg.open_store(memory=True)
    sg.load(store, [path])
    [row] = sg.query(store, "program-summary").rows
    assert row["project"] == "FIRST PROJECT" and row["workpiece"] == "SHAFT 42 BLANK D60X150"
