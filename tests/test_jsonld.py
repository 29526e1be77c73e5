"""JSON-LD: the generated context, the export (compact and tree), and loading JSON-LD back."""

from __future__ import annotations

import json
import re
import socket
import threading
from pathlib import Path
from typing import Any

import pyoxigraph as ox
import pytest
import rdflib
from click.testing import CliRunner

import stepnc_graph as sg
from stepnc_graph.cli import main
from stepnc_graph.jsonld import shipped_context
from stepnc_graph.jsonld_load import JsonLdError, local_contexts
from stepnc_graph.naming import CONTEXT_IRI, P21_NS, STEPNC_NS
from stepnc_graph.sources import SourceError
from stepnc_graph.store import GraphStore

from conftest import FIXTURES, ROOT
from test_load import assert_round_trip, canonical, unreadable_ids

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
PROGRAMS = sorted((FIXTURES / "p21").glob("*.stp")) + [EXAMPLE]
XSD = "http://www.w3.org/2001/XMLSchema#"
FORMATS = ("jsonld", "jsonld-tree")


def loaded(path: Path = EXAMPLE) -> tuple[GraphStore, sg.LoadResult]:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], lenient=True)
    return store, r


def value_normalised(quads: list[ox.Quad]) -> set[str]:
    """Quads as the store keeps them (it normalises literals: "2.0E0"^^xsd:double is 2), blank
    nodes canonicalised, the graph name dropped."""
    store = ox.Store()
    store.extend(ox.Quad(q.subject, q.predicate, q.object, ox.DefaultGraph()) for q in quads)
    ds = ox.Dataset(list(store))
    ds.canonicalize(ox.CanonicalizationAlgorithm.RDFC_1_0)
    return {str(q) for q in ds}


def parsed_by_rdflib(data: bytes | str) -> list[ox.Quad]:
    ds = rdflib.Dataset()
    ds.parse(data=data if isinstance(data, str) else data.decode("utf-8"), format="json-ld")
    return list(ox.parse(ds.serialize(format="nquads").encode("utf-8"), ox.RdfFormat.N_QUADS))


# -- the context -------------------------------------------------------------------------------


def test_context_has_type_scoped_terms_lists_references_items_and_datatypes() -> None:
    ctx = json.loads((ROOT / "ontology" / "context.jsonld").read_text(encoding="utf-8"))["@context"]
    assert ctx["@version"] == 1.1 and ctx["stepnc"] == STEPNC_NS and ctx["p21"] == P21_NS
    ws = ctx["machining_workingstep"]
    assert ws["@id"] == "stepnc:machining_workingstep"
    assert ws["@context"]["its_id"] == "stepnc:executable.its_id"  # inherited, scoped by the class
    assert ws["@context"]["its_operation"] == {"@id": "stepnc:machining_workingstep.its_operation", "@type": "@id"}
    assert ctx["machining_operation"]["@context"]["its_id"] == "stepnc:machining_operation.its_id"
    assert ctx["cartesian_point"]["@context"]["coordinates"] == {
        "@id": "stepnc:cartesian_point.coordinates", "@container": "@list", "@type": "xsd:double"}
    tech = ctx["turning_technology"]["@context"]
    assert tech["feedrate"] == {"@id": "stepnc:technology.feedrate", "@type": "xsd:double"}
    assert tech["feedrate_reference"]["@type"] == "@vocab"
    assert tech["feedrate_reference"]["@context"]["tcp"] == "stepnc:tool_reference_point.tcp"
    assert ctx["workpiece"]["@context"]["clamping_positions"]["@container"] == "@set"


# -- export ------------------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.stem)
def test_export_expands_to_exactly_the_graph(path: Path, fmt: str) -> None:
    # a JSON-LD processor (rdflib's) reads back every triple of the store, nothing else
    store, r = loaded(path)
    data = sg.export(store, fmt, r.graph)
    got = parsed_by_rdflib(data)
    assert {q.graph_name for q in got} == {ox.NamedNode(r.graph)}
    assert value_normalised(got) == value_normalised(list(store.quads(r.graph)))


@pytest.mark.parametrize("fmt", FORMATS)
def test_pyld_reads_the_same_graph(fmt: str) -> None:
    # a second, independent JSON-LD 1.1 processor agrees (where it is installed)
    jsonld = pytest.importorskip("pyld.jsonld")
    store, r = loaded(FIXTURES / "p21" / "pass_seed_annex_e.stp")

    def no_fetch(url: str, options: Any = None) -> Any:
        raise AssertionError(f"fetched {url}")

    doc = json.loads(sg.export(store, fmt, r.graph))
    nquads = jsonld.to_rdf(doc, {"format": "application/n-quads", "documentLoader": no_fetch})
    got = list(ox.parse(nquads.encode("utf-8"), ox.RdfFormat.N_QUADS))
    assert value_normalised(got) == value_normalised(list(store.quads(r.graph)))


def test_export_is_compact_and_readable() -> None:
    store, r = loaded()
    doc = json.loads(sg.export(store, "jsonld", r.graph))
    base = r.graph + "/"
    assert doc["@id"] == r.graph and doc["@context"]["@base"] == base
    nodes = {n["@id"]: n for n in doc["@graph"]}
    ws = nodes["i30"]
    assert ws["@type"] == "machining_workingstep"
    assert ws["its_id"] == "WS1 FACE RIGHT ROUGH" and ws["its_operation"] == "i50" and ws["its_feature"] == "i40"
    assert list(ws)[:3] == ["@id", "@type", "its_id"]  # Part 21 order after @id and @type
    assert nodes["i201"]["coordinates"] == ["0", "0", "0"]  # a list is an array, REALs are exact strings
    assert nodes["i70"]["feedrate"] == "0.25" and nodes["i70"]["feedrate_reference"] == "tcp"
    assert nodes["i1"]["its_workpieces"] == ["i10"]  # a SET is always an array
    # the context embedded is the shipped one, restricted to the classes the document uses
    shipped = shipped_context().source
    assert doc["@context"]["machining_workingstep"] == shipped["machining_workingstep"]
    assert "milling_machine_functions" not in doc["@context"]
    text = json.dumps(doc)
    assert "rdf:first" not in text and "_:" not in text  # no list chains, no blank node labels


def test_tree_nests_project_workplans_workingsteps_operation_tool_feature() -> None:
    store, r = loaded()
    doc = json.loads(sg.export(store, "jsonld-tree", r.graph))
    [project] = [n for n in doc["@graph"] if n.get("@type") == "project"]
    main_plan = project["main_workplan"]
    setup1 = main_plan["its_elements"][0]
    assert setup1["@type"] == "workplan" and setup1["its_id"] == "SETUP 1 - RIGHT END"
    ws = setup1["its_elements"][0]
    assert ws["its_id"] == "WS1 FACE RIGHT ROUGH"
    assert ws["its_operation"]["@type"] == "facing_rough"
    assert ws["its_operation"]["its_tool"]["its_id"] == "T01 CNMG 120408"
    assert ws["its_feature"]["@type"] == "revolved_flat"
    assert project["its_workpieces"][0]["its_id"] == "SHAFT 42 BLANK D60X150"  # nearest the project
    # each instance is written once; later uses refer to it
    assert setup1["its_elements"][1]["its_feature"] == "i40"
    ids = []

    def walk(value: Any) -> None:
        if isinstance(value, dict):
            if "@id" in value and len(value) > 1:
                ids.append(value["@id"])
            for v in value.values():
                walk(v)
        elif isinstance(value, list):
            for v in value:
                walk(v)

    walk(doc["@graph"])
    assert len(ids) == len(set(ids)) and len([i for i in ids if re.fullmatch(r"i\d+", i)]) == r.instances


def test_whole_store_export_keeps_graph_names(tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    results = sg.load(store, [EXAMPLE, FIXTURES / "p21" / "pass_edition3.stp"])
    got = parsed_by_rdflib(sg.export(store, "jsonld"))
    assert {q.graph_name.value for q in got if isinstance(q.graph_name, ox.NamedNode)} == {
        r.graph for r in results}
    assert len(got) == sum(store.count(r.graph) for r in results)


def test_tree_export_is_deterministic(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    exports = []
    for _ in range(2):
        store, r = loaded()
        exports.append(sg.export(store, "jsonld-tree", r.graph))
    assert exports[0] == exports[1]


# -- what a JavaScript consumer does to it -------------------------------------------------------


def javascript(value: Any, numbers: bool = False) -> Any:
    """``JSON.stringify(JSON.parse(...))``: a whole number is written without '.0'; ``numbers``: the
    consumer also turned every numeric string into a number (``parseFloat``) before writing back."""
    if isinstance(value, float) and value.is_integer():
        return int(value)
    if numbers and isinstance(value, str):
        try:
            number = float(value)
        except ValueError:
            return value
        return int(number) if number.is_integer() else number
    if isinstance(value, list):
        return [javascript(v, numbers) for v in value]
    if isinstance(value, dict):
        return {k: (v if k in ("@id", "@type", "@context") else javascript(v, numbers)) for k, v in value.items()}
    return value


@pytest.mark.parametrize("numbers", [False, True], ids=["as-written", "strings-made-numbers"])
def test_reals_stay_doubles_after_a_javascript_round_trip(numbers: bool, tmp_path: Path) -> None:
    store, r = loaded()
    doubles = sum(1 for q in store.quads(r.graph) if isinstance(q.object, ox.Literal)
                  and q.object.datatype.value == XSD + "double")
    assert doubles == 105
    doc = javascript(json.loads(sg.export(store, "jsonld", r.graph)), numbers)
    if numbers:
        assert doc["@graph"][1]["p21:id"] == 1 and isinstance(
            next(n for n in doc["@graph"] if n["@id"] == "i201")["coordinates"][0], int)
    path = tmp_path / "from_javascript.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    [back] = sg.load(store, [path], base_iri=r.graph + "-js")
    after = sum(1 for q in store.quads(back.graph) if isinstance(q.object, ox.Literal)
                and q.object.datatype.value == XSD + "double")
    assert after == doubles  # none became an integer
    assert canonical(store, r.graph) == canonical(store, back.graph)
    assert_round_trip(store, back.graph, tmp_path)


def test_the_old_export_lost_reals_to_javascript_which_the_measure_shows() -> None:
    # bench/jsonld_measure.py prints these figures; the "before" export is rebuilt there
    import importlib.util

    spec = importlib.util.spec_from_file_location("jsonld_measure", ROOT / "bench" / "jsonld_measure.py")
    assert spec is not None and spec.loader is not None
    measure = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(measure)
    store, r = loaded()
    old = measure.before(store, r.graph)
    assert measure.datatypes(measure.javascript_round_trip(old))["double"] < 105
    new = sg.export(store, "jsonld", r.graph)
    assert measure.datatypes(measure.javascript_round_trip(new))["double"] == 105


# -- import ------------------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("path", PROGRAMS, ids=lambda p: p.stem)
def test_part21_rdf_jsonld_rdf_part21_round_trip(path: Path, fmt: str, tmp_path: Path) -> None:
    store, r = loaded(path)
    exported = tmp_path / f"{path.stem}.jsonld"
    exported.write_bytes(sg.export(store, fmt, r.graph))
    [back] = sg.load(store, [exported], base_iri=r.graph + "-back")
    exclude = unreadable_ids(r)
    assert back.instances == r.instances and back.diagnostics == []
    assert canonical(store, r.graph, exclude) == canonical(store, back.graph, exclude)
    assert_round_trip(store, back.graph, tmp_path, exclude=exclude)  # its Part 21 loads to the same graph
    assert sg.export(store, "p21", back.graph) == sg.export(store, "p21", r.graph).replace(
        r.graph.encode(), back.graph.encode())


def test_a_jsonld_file_loads_as_the_graph_it_names_and_keeps_provenance(tmp_path: Path) -> None:
    store, r = loaded()
    exported = tmp_path / "sent_back.jsonld"
    exported.write_bytes(sg.export(store, "jsonld", r.graph))
    with pytest.raises(SourceError, match="--replace"):  # the graph holds the .stp file
        sg.load(store, [exported])
    [back] = sg.load(store, [exported], replace=True)
    assert back.graph == r.graph and sg.api.program_graphs(store) == [r.graph]
    rows = {(str(row["p"].value), str(row["o"].value)) for row in store.query(
        f"SELECT ?p ?o WHERE {{ GRAPH <{r.graph}> {{ <{r.graph}> ?p ?o }} }}")}
    prov = "http://www.w3.org/ns/prov#"
    assert (prov + "hadPrimarySource", exported.resolve().as_uri()) in rows
    assert (prov + "wasDerivedFrom", EXAMPLE.resolve().as_uri()) in rows
    assert ("http://purl.org/dc/terms/source", str(exported.resolve())) in rows
    assert (P21_NS + "instanceCount", "89") in rows
    activity = list(store.query(f"SELECT ?used WHERE {{ GRAPH <{r.graph}> {{ <{r.graph}/load> "
                                f"<{prov}used> ?used }} }}"))
    assert [row[0].value for row in activity] == [exported.resolve().as_uri()]


def test_base_iri_moves_the_document_to_another_graph(tmp_path: Path) -> None:
    store, r = loaded()
    exported = tmp_path / "copy.jsonld"
    exported.write_bytes(sg.export(store, "jsonld-tree", r.graph))
    [back] = sg.load(store, [exported], base_iri="https://plm.example.com/programs/42")
    iris = {q.subject.value for q in store.quads(back.graph) if isinstance(q.subject, ox.NamedNode)}
    assert "https://plm.example.com/programs/42/i30" in iris
    assert "https://plm.example.com/programs/42/id/executable/WS1%20FACE%20RIGHT%20ROUGH" in iris
    assert not any(i.startswith(r.graph) for i in iris)


@pytest.mark.parametrize("graph", ["urn:example:programs:42", "https://plm.example.com/programs#42"])
def test_graphs_without_a_hierarchical_base_are_written_with_absolute_iris(graph: str, tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EXAMPLE], base_iri=graph)
    data = sg.export(store, "jsonld", r.graph)
    doc = json.loads(data)
    assert "@base" not in doc["@context"] and doc["@id"] == graph
    assert value_normalised(parsed_by_rdflib(data)) == value_normalised(list(store.quads(r.graph)))
    path = tmp_path / "abs.jsonld"
    path.write_bytes(data)
    fresh = sg.open_store(memory=True)
    [back] = sg.load(fresh, [path])
    assert back.graph == graph and canonical(fresh, graph) == canonical(store, graph)


def test_aliases_follow_an_edited_its_id(tmp_path: Path) -> None:
    store, r = loaded()
    doc = json.loads(sg.export(store, "jsonld", r.graph))
    ws = next(n for n in doc["@graph"] if n["@id"] == "i30")
    ws["its_id"] = "WS1 FACE RIGHT ROUGH (PLM REV B)"
    path = tmp_path / "edited.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    [back] = sg.load(store, [path], base_iri="https://plm.example.com/p")
    subjects = {q.subject.value for q in store.quads(back.graph)}
    assert "https://plm.example.com/p/id/executable/WS1%20FACE%20RIGHT%20ROUGH%20%28PLM%20REV%20B%29" in subjects
    assert "https://plm.example.com/p/id/executable/WS1%20FACE%20RIGHT%20ROUGH" not in subjects
    assert b"#30=MACHINING_WORKINGSTEP('WS1 FACE RIGHT ROUGH (PLM REV B)',#22,#40,#50,$);" in sg.export(
        store, "p21", back.graph)


def test_the_shipped_context_can_be_named_by_its_iri(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    refuse_network(monkeypatch)
    store, r = loaded()
    doc = json.loads(sg.export(store, "jsonld", r.graph))
    doc["@context"] = [CONTEXT_IRI, {"@base": doc["@context"]["@base"]}]
    path = tmp_path / "by_iri.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    [back] = sg.load(store, [path], base_iri=r.graph + "-iri")
    assert canonical(store, r.graph) == canonical(store, back.graph)


# -- no network, ever ----------------------------------------------------------------------------


def refuse_network(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Make every connection attempt fail and record it."""
    attempts: list[Any] = []

    def refuse(*args: Any, **kwargs: Any) -> Any:
        attempts.append(args)
        raise AssertionError(f"network access while loading JSON-LD: {args}")

    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket.socket, "connect_ex", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    monkeypatch.setattr(socket, "getaddrinfo", refuse)
    return attempts


def with_context(context: Any, tmp_path: Path) -> Path:
    store, r = loaded()
    doc = json.loads(sg.export(store, "jsonld", r.graph))
    doc["@context"] = [context, doc["@context"]]
    path = tmp_path / "remote.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


@pytest.mark.parametrize("where", ["document", "node", "scoped", "import", "file"])
def test_a_context_that_would_be_fetched_is_refused_without_any_connection(
        where: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    listener = socket.socket()  # a server that would hang a fetch: it never accepts
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    url = f"http://127.0.0.1:{listener.getsockname()[1]}/context.jsonld"
    attempts = refuse_network(monkeypatch)
    store, r = loaded()
    doc = json.loads(sg.export(store, "jsonld", r.graph))
    if where == "document":
        doc["@context"] = [url, doc["@context"]]
    elif where == "node":
        doc["@graph"][1]["@context"] = url
    elif where == "scoped":
        doc["@context"]["project"] = {"@id": "stepnc:project", "@context": url}
    elif where == "import":
        doc["@context"]["@import"] = url
    else:
        url = (tmp_path / "local.jsonld").as_uri()
        doc["@context"] = [url, doc["@context"]]
    path = tmp_path / "remote.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(JsonLdError, match="never fetches contexts") as caught:
        sg.load(store, [path], base_iri=r.graph + "-remote")
    assert url in str(caught.value)
    assert attempts == []
    listener.setblocking(False)
    with pytest.raises(BlockingIOError):  # nobody knocked
        listener.accept()
    listener.close()
    assert not store.has_graph(r.graph + "-remote")


def test_local_contexts_leaves_inline_contexts_alone() -> None:
    doc = {"@context": {"ex": "http://example.com/"}, "ex:p": 1}
    assert local_contexts(json.loads(json.dumps(doc)), "x") == doc


def test_the_reader_never_opens_a_connection_for_a_context_given_inline(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    attempts = refuse_network(monkeypatch)
    store, r = loaded()
    path = tmp_path / "inline.jsonld"
    path.write_bytes(sg.export(store, "jsonld", r.graph))
    done = threading.Event()
    sg.load(store, [path], base_iri=r.graph + "-inline")
    done.set()
    assert attempts == [] and store.has_graph(r.graph + "-inline")


# -- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize("text,message", [
    ('{"@context": {}, "@graph": [\n  {"@id": "x",}\n]}', r"bad\.jsonld:2:15: not JSON"),
    (b"{\"a\": \"\xff\"}", r"bad\.jsonld:1:8: not UTF-8"),
    ('{"@id": "http://x/g", "@graph": [{"@id": "http://x/a", "http://x/p": 1}]}', "holds no STEP-NC instance"),
    ('{"@graph": [{"@id": "http://x/g1", "@graph": [{"@id": "http://x/a", "http://x/p": 1}]},'
     ' {"@id": "http://x/g2", "@graph": [{"@id": "http://x/b", "http://x/p": 1}]}]}', "holds 2 graphs"),
    ('{"@context": 5, "@id": "http://x/a", "http://x/p": 1}', "not JSON-LD that can be read"),
    ('{"@id": "http://x/a", "http://x/p": ' + "[" * 100000 + "]" * 100000 + "}", "nested too deeply"),
    ('{"@context": {"a": "b:x", "b": "a:y"}, "@id": "http://x/a", "a": 1}', "not JSON-LD that can be read"),
])
def test_bad_documents_are_refused_with_where_and_why(text: str | bytes, message: str, tmp_path: Path) -> None:
    path = tmp_path / "bad.jsonld"
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
    store = sg.open_store(memory=True)
    with pytest.raises(JsonLdError, match=message):
        sg.load(store, [path], base_iri="https://example.com/g")
    assert store.graphs() == []


def test_a_reference_outside_the_program_cannot_be_written_back(tmp_path: Path) -> None:
    store, r = loaded()
    doc = json.loads(sg.export(store, "jsonld", r.graph))
    next(n for n in doc["@graph"] if n["@id"] == "i30")["its_feature"] = "https://plm.example.com/features/9"
    path = tmp_path / "outside.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(JsonLdError, match="cannot be written back as Part 21"):
        sg.load(store, [path], base_iri=r.graph + "-outside")


def test_cli_loads_jsonld_and_reports_bad_input_with_exit_2(tmp_path: Path) -> None:
    store_dir = tmp_path / "store"
    runner = CliRunner()
    assert runner.invoke(main, ["load", "--store", str(store_dir), str(EXAMPLE)]).exit_code == 0
    out = tmp_path / "shaft.jsonld"
    done = runner.invoke(main, ["export", "--store", str(store_dir), "--format", "jsonld", "-o", str(out)])
    assert done.exit_code == 0, done.output
    done = runner.invoke(main, ["load", "--store", str(store_dir), "--replace", str(out)])
    assert done.exit_code == 0, done.output
    assert "89 instances" in done.output and "shaft_two_setups.stp" in done.output
    bad = tmp_path / "bad.jsonld"
    bad.write_text("{", encoding="utf-8")
    done = runner.invoke(main, ["load", "--store", str(store_dir), "--format", "json", str(bad)])
    assert done.exit_code == 2
    [error] = json.loads(done.output)["errors"]
    assert error["type"] == "JsonLdError" and error["line"] == 1 and "not JSON" in error["message"]


def test_a_directory_load_takes_jsonld_files_too(tmp_path: Path) -> None:
    store, r = loaded()
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "a.jsonld").write_bytes(sg.export(store, "jsonld", r.graph))
    fresh = sg.open_store(memory=True)
    [back] = sg.load(fresh, [tmp_path / "in"])
    assert back.graph == r.graph  # the graph the document names
    assert canonical(fresh, back.graph) == canonical(store, r.graph)
