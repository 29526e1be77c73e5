"""`link`: PLM identifiers attached to program entities in link graphs; the documented queries."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pyoxigraph as ox
import pytest
from click.testing import CliRunner

import stepnc_graph as sg
from stepnc_graph.cli import main
from stepnc_graph.loading.link import LinkError, program_link_graphs
from stepnc_graph.core.naming import P21_NS, link_graph_iri
from stepnc_graph.loading.sources import SourceError
from stepnc_graph.store import GraphStore
from stepnc_graph.core.naming import listed_graphs

from conftest import ROOT
from test_load import canonical

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
MAPPING = ROOT / "examples" / "shaft_plm_links.csv"
DOCS = ROOT / "docs" / "linked-data.md"
DCT = "http://purl.org/dc/terms/"
OWL_SAME_AS = "http://www.w3.org/2002/07/owl#sameAs"
T01_STEPS = ["WS1 FACE RIGHT ROUGH", "WS2 FACE RIGHT FINISH", "WS3 OD50 ROUGH", "WS4 OD50 FINISH",
             "WS6 FACE LEFT FINISH", "WS7 OD40 ROUGH", "WS8 OD40 FINISH"]


def loaded() -> tuple[GraphStore, str]:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EXAMPLE])
    return store, r.graph


def documented_query(heading: str) -> str:
    """The first SPARQL block after ``heading`` in docs/linked-data.md."""
    text = DOCS.read_text(encoding="utf-8").split(heading, 1)[1]
    return text.split("```sparql\n", 1)[1].split("```", 1)[0]


def triples(store: GraphStore, graph: str) -> set[tuple[str, str, str]]:
    return {(q.subject.value, q.predicate.value, q.object.value) for q in store.quads(graph)}  # type: ignore[union-attr]


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_links_go_to_their_own_graph_through_aliases(tmp_path: Path) -> None:
    store, graph = loaded()
    before = canonical(store, graph)
    p21_before = sg.export(store, "p21", graph)
    result = sg.link(store, MAPPING, graph)
    assert result.links == 5 and result.problems == []
    target = link_graph_iri(graph, "shaft_plm_links.csv")
    assert result.link_graph == target == graph + "/links/shaft_plm_links.csv"
    links = triples(store, target)
    alias = graph + "/id/machining_tool/T01%20CNMG%20120408"
    assert (alias, DCT + "identifier", "SANDVIK CNMG 12 04 08-PM 4325") in links
    assert (alias, OWL_SAME_AS, "https://plm.example.com/tools/TOOL-4711") in links
    assert (graph + "/id/executable/WS5%20RELIEF%20GROOVE", DCT + "identifier", "DOC-0815 rev C") in links
    assert (graph + "/i40", DCT + "identifier", "DRW-100-2042 zone B3") in links  # found by #id
    # the program graph is as loaded, and so is its Part 21 export
    assert canonical(store, graph) == before and sg.export(store, "p21", graph) == p21_before


def test_the_documented_query_joins_a_plm_item_to_the_workingsteps_that_use_it() -> None:
    store, graph = loaded()
    sg.link(store, MAPPING, graph)
    rows = store.query(documented_query("### Which workingsteps use a PLM item"))
    assert [row["step"].value for row in rows] == T01_STEPS
    by_iri = documented_query("### Which workingsteps use a PLM item").replace(
        '?item dcterms:identifier "SANDVIK CNMG 12 04 08-PM 4325"',
        "?item owl:sameAs <https://plm.example.com/tools/TOOL-4711>")
    assert [row["step"].value for row in store.query(by_iri)] == T01_STEPS


def test_links_survive_a_reload_of_a_renumbered_program(tmp_path: Path) -> None:
    store, graph = loaded()
    sg.link(store, MAPPING, graph)
    text = EXAMPLE.read_text(encoding="utf-8")
    renumbered = re.sub(r"#(\d+)", lambda m: f"#{int(m.group(1)) + 1000}", text)  # what a CAM system does
    path = write(tmp_path, "shaft_two_setups.stp", renumbered)
    [again] = sg.load(store, [path], base_iri=graph, replace=True)
    assert again.graph == graph and program_link_graphs(store, graph) == [graph + "/links/shaft_plm_links.csv"]
    rows = list(store.query(documented_query("### Which workingsteps use a PLM item")))
    assert [row["step"].value for row in rows] == T01_STEPS
    steps = {row["workingstep"].value for row in rows}
    assert graph + "/i1030" in steps and graph + "/i30" not in steps


def test_unload_removes_the_program_with_its_link_graphs() -> None:
    store, graph = loaded()
    sg.link(store, MAPPING, graph)
    assert store.has_graph(graph + "/links/shaft_plm_links.csv")
    assert sg.unload(store, graph)
    assert listed_graphs(store) == []


def test_a_link_graph_records_its_provenance_and_the_documented_query_lists_it(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    store, graph = loaded()
    result = sg.link(store, MAPPING, graph)
    prov = "http://www.w3.org/ns/prov#"
    meta = triples(store, result.link_graph)
    g = result.link_graph
    assert (g, "http://www.w3.org/1999/02/22-rdf-syntax-ns#type", P21_NS + "LinkGraph") in meta
    assert (g, P21_NS + "linkedProgram", graph) in meta
    assert (g, prov + "hadPrimarySource", MAPPING.resolve().as_uri()) in meta
    assert (g, prov + "generatedAtTime", "2023-11-14T22:13:20Z") in meta
    assert (g + "/link", prov + "used", graph) in meta
    rows = {(row["graph"].value, row["source"].value) for row in store.query(documented_query("## Provenance"))}
    assert rows == {(graph, str(EXAMPLE.resolve())), (g, str(MAPPING.resolve()))}


def test_unknown_and_ambiguous_rows_are_listed_and_nothing_is_linked(tmp_path: Path) -> None:
    store, graph = loaded()
    mapping = write(tmp_path, "bad.csv", "its_id,scope,p21_id,identifier\n"
                                         "T01 CNMG 120408,machining_tool,,ok\n"
                                         "NO SUCH TOOL,,,x\n"
                                         ",,999,y\n"
                                         "SETUP 1,workpiece,,z\n"
                                         "T01 CNMG 120408,,7,both\n"
                                         ",,abc,n\n"
                                         "WS1 FACE RIGHT ROUGH,,,\n"
                                         "OD 50,no_such_entity,,w\n")
    with pytest.raises(LinkError) as caught:
        sg.link(store, mapping, graph)
    problems = {p.line: p.message for p in caught.value.problems}
    assert problems == {
        3: "no instance of the program has this its_id",
        4: "the program has no instance #999",
        5: "no instance of the program has this its_id in scope workpiece",
        6: "give either its_id or p21_id",
        7: "p21_id must be an instance number such as 30 or #30, not 'abc'",
        8: "nothing to attach: give identifier and/or same_as",
        9: "scope 'no_such_entity' is not an entity of the schema",
    }
    assert "7 of 8 rows" in str(caught.value)
    assert program_link_graphs(store, graph) == []


def test_a_label_two_instances_share_needs_a_scope_or_the_p21_id(tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    text = EXAMPLE.read_text(encoding="utf-8").replace("#37=MACHINING_WORKINGSTEP('WS8 OD40 FINISH'",
                                                       "#37=MACHINING_WORKINGSTEP('OD 40'")
    [r] = sg.load(store, [write(tmp_path, "shared.stp", text)])
    shared = write(tmp_path, "shared.csv", "its_id,identifier\nOD 40,x\n")
    with pytest.raises(LinkError, match=r"2 instances have this its_id \(#37 machining_workingstep, #44 "
                                        r"outer_diameter\); add a scope or give the p21_id"):
        sg.link(store, shared, r.graph)
    scoped = write(tmp_path, "scoped.csv", "its_id,scope,identifier\nOD 40,manufacturing_feature,x\n")
    assert sg.link(store, scoped, r.graph).links == 1
    assert (r.graph + "/id/manufacturing_feature/OD%2040", DCT + "identifier", "x") in triples(
        store, r.graph + "/links/scoped.csv")


def test_allow_unknown_links_the_rest_and_reports(tmp_path: Path) -> None:
    store, graph = loaded()
    mapping = write(tmp_path, "some.json", json.dumps({"links": [
        {"its_id": "SHAFT-42", "identifier": "PN 1"},
        {"p21_id": "#30", "same_as": "https://plm.example.com/ops/30"},
        {"p21_id": 4000, "identifier": "gone"},
        {"its_id": "X", "same_as": "not an iri"},
    ]}))
    result = sg.link(store, mapping, graph, allow_unknown=True)
    assert result.links == 2 and [p.line for p in result.problems] == [3, 4]
    assert "not an absolute IRI" in result.problems[1].message
    links = triples(store, result.link_graph)
    assert (graph + "/i30", OWL_SAME_AS, "https://plm.example.com/ops/30") in links


def test_linking_again_replaces_and_another_file_of_the_same_name_needs_replace(tmp_path: Path) -> None:
    store, graph = loaded()
    first = write(tmp_path, "links.csv", "its_id,identifier\nSHAFT-42,PN 1\n")
    sg.link(store, first, graph)
    write(tmp_path, "links.csv", "its_id,identifier\nSHAFT-42,PN 2\n")
    sg.link(store, first, graph)
    ids = {o for _, p, o in triples(store, graph + "/links/links.csv") if p == DCT + "identifier"}
    assert ids == {"PN 2"}
    (tmp_path / "other").mkdir()
    other = write(tmp_path / "other", "links.csv", "its_id,identifier\nSHAFT-42,PN 3\n")
    with pytest.raises(SourceError, match="replace=True"):
        sg.link(store, other, graph)
    sg.link(store, other, graph, replace=True)


@pytest.mark.parametrize("text,message", [
    ("identifier,colour\nx,red\n", "the first line must name the columns"),
    ("", "the first line must name the columns"),
])
def test_unreadable_mappings(text: str, message: str, tmp_path: Path) -> None:
    store, graph = loaded()
    with pytest.raises(LinkError, match=message):
        sg.link(store, write(tmp_path, "m.csv", text), graph)
    with pytest.raises(LinkError, match="not JSON"):
        sg.link(store, write(tmp_path, "m.json", "[{"), graph)


def test_a_store_of_several_programs_needs_the_graph(tmp_path: Path) -> None:
    store, graph = loaded()
    sg.load(store, [EXAMPLE], base_iri="https://example.com/copy")
    with pytest.raises(SourceError, match="holds 2 programs"):
        sg.link(store, MAPPING)


def test_cli_link_exit_codes(tmp_path: Path) -> None:
    store_dir = str(tmp_path / "store")
    runner = CliRunner()
    assert runner.invoke(main, ["load", "--store", store_dir, str(EXAMPLE)]).exit_code == 0
    mapping = shutil.copy(MAPPING, tmp_path / "links.csv")
    done = runner.invoke(main, ["link", "--store", store_dir, str(mapping)])
    assert done.exit_code == 0, done.output
    assert "linked 5 entities" in done.output and "/links/links.csv" in done.output
    bad = write(tmp_path, "bad.csv", "its_id,identifier\nSHAFT-42,PN\nNOPE,x\n")
    done = runner.invoke(main, ["link", "--store", store_dir, str(bad)])
    assert done.exit_code == 2 and "line 3: its_id 'NOPE': no instance" in done.output
    done = runner.invoke(main, ["link", "--store", store_dir, "--allow-unknown", "--format", "json", str(bad)])
    assert done.exit_code == 1
    assert json.loads(done.output)["problems"] == [
        {"line": 3, "key": "its_id 'NOPE'", "message": "no instance of the program has this its_id"}]
    done = runner.invoke(main, ["link", "--store", store_dir, "--graph", "not an iri", str(mapping)])
    assert done.exit_code == 2 and "no graph not an iri in the store" in done.output
    store = sg.open_store(Path(store_dir), readonly=True)
    with store:
        assert len(program_link_graphs(store, sg.info(store)[0].graph)) == 2
        assert ox.NamedNode(sg.info(store)[0].graph)  # the program is still listed alone
        assert [i.graph for i in sg.info(store)] == ["https://w3id.org/stepnc-graph/data/shaft_two_setups.stp"]


# -- hostile mappings (issue 26) ---------------------------------------------------------------

#: what a message about a mapping must not show: Python's insides
INTERNALS = re.compile(r"Traceback|Error:|Exception|<class |object at 0x|field limit|Exceeds the limit|recursion")


def link_error(tmp_path: Path, name: str, text: str) -> LinkError:
    """The LinkError linking ``text`` raises: nothing linked, a message about the mapping."""
    store, graph = loaded()
    with pytest.raises(LinkError) as caught:
        sg.link(store, write(tmp_path, name, text), graph)
    assert not INTERNALS.search(str(caught.value)), str(caught.value)
    assert program_link_graphs(store, graph) == []
    return caught.value


def test_a_csv_field_too_long_is_a_clear_error_with_line_and_column(tmp_path: Path) -> None:
    error = link_error(tmp_path, "long.csv", "its_id,identifier\nSHAFT-42,PN 1\nSHAFT-42," + "x" * 200_000 + "\n")
    assert (error.line, error.column) == (3, 10)
    assert "identifier" in error.message and "131,072" in error.message
    assert str(error).startswith(f"{tmp_path / 'long.csv'}:3:10: ")
    # a quoted field over several lines is placed where it starts
    error = link_error(tmp_path, "quoted.csv", 'its_id,identifier\nSHAFT-42,"a\n' + "y" * 200_000 + '"\n')
    assert (error.line, error.column) == (2, 10)


def test_a_column_named_twice_is_refused_not_read_as_the_last(tmp_path: Path) -> None:
    error = link_error(tmp_path, "twice.csv", "its_id,identifier,Identifier \nSHAFT-42,PN 1,PN 2\n")
    assert (error.line, error.column) == (1, 19)
    assert "identifier" in error.message and "columns 2 and 3" in error.message


def test_a_json_key_given_twice_is_refused_not_read_as_the_last(tmp_path: Path) -> None:
    store, graph = loaded()
    text = '{"links": [{"its_id": "SHAFT-42", "identifier": "PN 1"},\n' \
           '           {"its_id": "SHAFT-42", "identifier": "PN 1", "identifier": "PN 2"}]}'
    with pytest.raises(LinkError) as caught:
        sg.link(store, write(tmp_path, "twice.json", text), graph)
    [problem] = caught.value.problems
    assert problem.line == 2 and problem.pointer == "/links/1"
    assert "identifier" in problem.message and "twice" in problem.message
    assert "/links/1" in str(caught.value)
    error = link_error(tmp_path, "top.json", '{"links": [], "links": [{"its_id": "SHAFT-42", "identifier": "x"}]}')
    assert error.pointer == "" and "links" in error.message


def test_a_deeply_nested_json_mapping_is_a_clear_error(tmp_path: Path) -> None:
    error = link_error(tmp_path, "deep.json", "[" * 100_000 + "]" * 100_000)
    assert "nested" in error.message


def test_a_huge_json_number_is_a_row_problem_not_a_crash(tmp_path: Path) -> None:
    store, graph = loaded()
    text = '[{"p21_id": ' + "9" * 5000 + ', "identifier": "x"}, {"p21_id": 30, "identifier": "y"}]'
    result = sg.link(store, write(tmp_path, "huge.json", text), graph, allow_unknown=True)
    assert result.links == 1
    [problem] = result.problems
    assert problem.line == 1 and "instance number" in problem.message and len(problem.message) < 300
    assert not INTERNALS.search(problem.message)


@pytest.mark.parametrize("name,text,where", [
    ("long.csv", "its_id,identifier\nSHAFT-42," + "x" * 200_000 + "\n", "long.csv:2:10: "),
    ("twice.csv", "its_id,identifier,identifier\nSHAFT-42,a,b\n", "twice.csv:1:"),
    ("deep.json", "[" * 100_000 + "]" * 100_000, "deep.json"),
])
def test_cli_link_hostile_mappings_exit_2_with_where(name: str, text: str, where: str, tmp_path: Path) -> None:
    store_dir = str(tmp_path / "store")
    runner = CliRunner()
    assert runner.invoke(main, ["load", "--store", store_dir, str(EXAMPLE)]).exit_code == 0
    mapping = write(tmp_path, name, text)
    done = runner.invoke(main, ["link", "--store", store_dir, str(mapping)])
    assert done.exit_code == 2, done.output
    assert where in done.output and "Traceback" not in done.output and not INTERNALS.search(done.output)
    done = runner.invoke(main, ["link", "--store", store_dir, "--format", "json", str(mapping)])
    assert done.exit_code == 2
    [error] = json.loads(done.output)["errors"]
    assert error["type"] == "LinkError" and "line" in error
