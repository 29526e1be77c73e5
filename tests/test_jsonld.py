"""JSON-LD: the generated context, the export (compact and tree), and loading JSON-LD back."""

from __future__ import annotations

import functools
import http.server
import json
import os
import re
import socket
import threading
import time
from collections.abc import Iterator
from decimal import Decimal
from pathlib import Path
from typing import Any

import pyoxigraph as ox
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
import rdflib
from click.testing import CliRunner

import stepnc_graph as sg
from stepnc_graph.cli import main
from stepnc_graph.exporting.jsonld import shipped_context
from stepnc_graph.loading.jsonld import MAX_DEPTH, JsonLdError, local_contexts, parse_quads
from stepnc_graph.core.naming import CONTEXT_IRI, P21_NS, STEPNC_NS
from stepnc_graph.loading.sources import SourceError
from stepnc_graph.store import GraphStore
from stepnc_graph.core.naming import listed_graphs

from conftest import FIXTURES, ROOT
from test_load import assert_round_trip, canonical, unreadable_ids

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
# the editions fixtures: graphs read in another edition (fdis2001), whole or mixed with 2002 instances
PROGRAMS = sorted((FIXTURES / "p21").glob("*.stp")) + sorted((FIXTURES / "editions").glob("plate_*.stp")) + [EXAMPLE]
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


def test_an_unreadable_instance_typed_only_unreadable_is_still_counted(tmp_path: Path) -> None:
    # found by bench/fuzz_load.py (input 1016029): a flipped byte made the p21:RawInstance type of
    # an unreadable instance another IRI; the document still loads (its text is kept, it is
    # unreadable), so the instance must be counted, as raw
    store, r = loaded(FIXTURES / "p21" / "fail_seed_annex_e.stp")
    assert r.unreadable > 0
    text = sg.export(store, "jsonld", r.graph).decode()
    both = re.compile(r'"p21:RawInstance",(\s*)"p21:UnreadableInstance"')
    assert both.search(text)
    path = tmp_path / "damaged.jsonld"
    path.write_text(both.sub(r'"pp21:RawInstance",\1"p21:UnreadableInstance"', text), encoding="utf-8")
    [back] = sg.load(store, [path], base_iri=r.graph + "-back")
    numbered = len(list(store.query(f"SELECT ?s WHERE {{ GRAPH <{back.graph}> {{ ?s <{P21_NS}id> ?id }} }}")))
    assert back.instances == numbered == r.instances and back.raw == r.raw


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
    ('{"@context": 5, "@id": "http://x/a", "http://x/p": 1}', r"bad\.jsonld at /@context: a @context is an object"),
    ('{"@id": "http://x/a", "http://x/p": ' + "[" * 100000 + "]" * 100000 + "}", "nested deeper than 500 levels"),
    ('{"@context": {"a": "b:x", "b": "a:y"}, "@id": "http://x/a", "a": 1}', "not JSON-LD that can be read"),
])
def test_bad_documents_are_refused_with_where_and_why(text: str | bytes, message: str, tmp_path: Path) -> None:
    path = tmp_path / "bad.jsonld"
    path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
    store = sg.open_store(memory=True)
    with pytest.raises(JsonLdError, match=message):
        sg.load(store, [path], base_iri="https://example.com/g")
    assert listed_graphs(store) == []


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


# -- hostile documents (issue 26) --------------------------------------------------------------

SMALL = FIXTURES / "p21" / "pass_edition3.stp"
#: what a fetched context would say: its_id and the project class mean something else
EVIL = {"@context": {"its_id": "https://attacker.example/renamed", "project": "https://attacker.example/Project",
                     "@vocab": "https://attacker.example/v/"}}
#: what a message about a document must not show: Python's or a library's insides
INTERNALS = re.compile(r"Traceback|Error:|Exception|rdflib|pyoxigraph|<class |object at 0x|\\\\x|File \"|"
                       r"invalid literal|int\(\)|with base 10|LoadDocumentCallback")


@functools.lru_cache(maxsize=None)
def small_export() -> tuple[str, str]:
    """The graph IRI and the ``jsonld`` export of the small edition-3 program (made once)."""
    store, r = loaded(SMALL)
    return r.graph, sg.export(store, "jsonld", r.graph).decode("utf-8")


def small_doc() -> Any:
    return json.loads(small_export()[1])


def node(doc: Any, at: str) -> dict[str, Any]:
    return next(n for n in doc["@graph"] if n["@id"] == at)  # type: ignore[no-any-return]


def last_token(pointer: str) -> str:
    return pointer.rsplit("/", 1)[-1].replace("~1", "/").replace("~0", "~")


def at_pointer(doc: Any, pointer: str) -> Any:
    """The value an RFC 6901 JSON pointer names."""
    for token in pointer.split("/")[1:]:
        token = token.replace("~1", "/").replace("~0", "~")
        doc = doc[int(token)] if isinstance(doc, list) else doc[token]
    return doc


class Listener:
    """A loopback HTTP server in a thread that records every connection it accepts and every
    request, and answers with :data:`EVIL`, a context that would change what the data means."""

    def __init__(self) -> None:
        self.connections: list[Any] = []
        self.requests: list[str] = []
        outer = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 (the name http.server calls)
                outer.requests.append(self.path)
                body = json.dumps(EVIL).encode("utf-8")
                self.send_response(200)
                self.send_header("Content-Type", "application/ld+json")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args: Any) -> None:
                pass

        class Server(http.server.ThreadingHTTPServer):
            def verify_request(self, request: Any, client_address: Any) -> bool:
                outer.connections.append(client_address)
                return True

        self.server = Server(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/context.jsonld"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def heard(self) -> list[Any]:
        return self.connections + self.requests

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


class FifoWatch:
    """A FIFO whose opening is seen: a thread keeps trying to open its write end, which succeeds
    only while a reader holds it open; if it ever does, it records that and feeds the reader
    :data:`EVIL`. A plain file's atime would not tell (relatime, noatime)."""

    def __init__(self, path: Path) -> None:
        os.mkfifo(path)
        self.path, self.uri = path, path.as_uri()
        self.opened: list[float] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._watch, daemon=True)
        self.thread.start()

    def _watch(self) -> None:
        while not self.stop.is_set():
            try:
                fd = os.open(self.path, os.O_WRONLY | os.O_NONBLOCK)
            except OSError:  # ENXIO: no reader
                time.sleep(0.002)
                continue
            self.opened.append(time.time())
            try:
                os.write(fd, json.dumps(EVIL).encode("utf-8"))
            finally:
                os.close(fd)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()


@pytest.fixture
def listener() -> Iterator[Listener]:
    server = Listener()
    yield server
    server.close()


@pytest.fixture
def fifo(tmp_path: Path) -> Iterator[FifoWatch]:
    watch = FifoWatch(tmp_path / "context-fifo.jsonld")
    yield watch
    watch.close()


def hostile_context(where: str, doc: Any, url: str) -> str:
    """Put a context named by ``url`` into ``doc`` at ``where``; the JSON pointer of the IRI."""
    ctx = doc["@context"]
    if where == "nested-array":  # the campaign's finding: the check looked only one array deep
        doc["@context"] = [ctx, [url]]
        return "/@context/1/0"
    if where == "nested-twice":
        doc["@context"] = [[[url]], ctx]
        return "/@context/0/0/0"
    if where == "document":
        doc["@context"] = [url, ctx]
        return "/@context/0"
    if where == "type-scoped":
        ctx["machining_workingstep"]["@context"] = [ctx["machining_workingstep"]["@context"], [url]]
        return "/@context/machining_workingstep/@context/1/0"
    if where == "property-scoped":
        scoped = ctx["machining_workingstep"]["@context"]
        scoped["its_id"] = {"@id": scoped["its_id"], "@context": [url]}
        return "/@context/machining_workingstep/@context/its_id/@context/0"
    if where == "import":
        ctx["@import"] = url
        return "/@context/@import"
    if where == "wrapped":  # a context object that holds a @context of its own
        doc["@context"] = [{"@context": [url]}, ctx]
        return "/@context/0/@context/0"
    if where == "node":
        i3 = doc["@graph"].index(node(doc, "i3"))
        doc["@graph"][i3]["@context"] = [{}, [url]]
        return f"/@graph/{i3}/@context/1/0"
    raise AssertionError(where)


HOSTILE_PLACES = ["nested-array", "nested-twice", "document", "type-scoped", "property-scoped", "import",
                  "wrapped", "node"]


@pytest.mark.parametrize("target", ["http", "fifo", "file", "etc-passwd"])
@pytest.mark.parametrize("where", HOSTILE_PLACES)
def test_no_context_is_fetched_or_read_however_deep_it_is(
        where: str, target: str, tmp_path: Path, listener: Listener, fifo: FifoWatch) -> None:
    evil_file = tmp_path / "evil-context.jsonld"
    evil_file.write_text(json.dumps(EVIL), encoding="utf-8")
    url = {"http": listener.url, "fifo": fifo.uri, "file": evil_file.as_uri(), "etc-passwd": "file:///etc/passwd"}[target]
    doc = small_doc()
    pointer = hostile_context(where, doc, url)
    path = tmp_path / "hostile.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    store = sg.open_store(memory=True)
    with pytest.raises(JsonLdError) as caught:
        sg.load(store, [path], base_iri="https://example.com/hostile")
    error = caught.value
    assert error.pointer == pointer and at_pointer(doc, pointer) == url
    assert url in str(error) and "never fetches contexts" in str(error)
    assert not INTERNALS.search(str(error))
    time.sleep(0.05)  # a fetch on another thread would have arrived by now
    assert listener.heard() == [] and fifo.opened == []
    assert listed_graphs(store) == []


def test_the_processor_itself_never_fetches(tmp_path: Path, listener: Listener, fifo: FifoWatch) -> None:
    # below the structural check: the JSON-LD processor is handed remote contexts directly, as if
    # the check had missed them; it has no way to load a document, so it refuses them too
    for url in (listener.url, fifo.uri, "file:///etc/passwd"):
        for doc in ({"@context": url, "@id": "https://example.com/a", "its_id": "x"},
                    {"@context": [{}, [url]], "@id": "https://example.com/a", "its_id": "x"},
                    {"@context": {"@import": url}, "@id": "https://example.com/a", "its_id": "x"},
                    {"@context": {"T": {"@id": "https://example.com/T", "@context": url}},
                     "@id": "https://example.com/a", "@type": "T", "its_id": "x"}):
            with pytest.raises(JsonLdError) as caught:
                parse_quads(doc, "https://example.com/", "direct.jsonld")
            assert not INTERNALS.search(str(caught.value))
    time.sleep(0.05)
    assert listener.heard() == [] and fifo.opened == []


def refused(doc: Any, tmp_path: Path, text: str | None = None, base_iri: str | None = "https://example.com/h"
            ) -> JsonLdError:
    """The error a load of ``doc`` (or of the JSON ``text``) raises: a JsonLdError that speaks of
    the document, not of Python; the store is left empty."""
    path = tmp_path / "hostile.jsonld"
    path.write_text(text if text is not None else json.dumps(doc), encoding="utf-8")
    store = sg.open_store(memory=True)
    with pytest.raises(JsonLdError) as caught:
        sg.load(store, [path], base_iri=base_iri)
    assert not INTERNALS.search(str(caught.value)), str(caught.value)
    assert listed_graphs(store) == []
    return caught.value


#: characters and pieces no IRI may hold (RFC 3987), as the campaign found them
BAD_IRI_PARTS = {
    "nul": "a\x00b", "space": "a b", "tab": "a\tb", "newline": "a\nb", "unit-separator": "a\x1fb",
    "delete": "a\x7fb", "c1-control": "a\x85b", "less-than": "a<b", "greater-than": "a>b", "quote": 'a"b',
    "left-brace": "a{b", "right-brace": "a}b", "pipe": "a|b", "caret": "a^b", "backquote": "a`b",
    "backslash": "a\\b", "percent-letters": "a%zzb", "percent-one-digit": "a%4", "percent-at-end": "a%",
}
IRI_PLACES = ["node-id", "reference", "type", "key", "coerced-reference", "datatype"]


def put_iri(doc: Any, place: str, iri: str) -> None:
    i3 = node(doc, "i3")
    if place == "node-id":
        doc["@graph"].append({"@id": iri, "https://plm.example.com/note": "dropped?"})
    elif place == "reference":
        i3["https://plm.example.com/ref"] = {"@id": iri}
    elif place == "type":
        i3["@type"] = ["machining_workingstep", iri]
    elif place == "key":
        i3[iri] = "dropped?"
    elif place == "coerced-reference":
        node(doc, "i2")["its_elements"] = [iri]
    elif place == "datatype":
        i3["https://plm.example.com/v"] = {"@value": "1", "@type": iri}


@pytest.mark.parametrize("place", IRI_PLACES)
@pytest.mark.parametrize("kind", list(BAD_IRI_PARTS))
def test_every_invalid_iri_is_a_clear_error_never_a_traceback_or_a_drop(kind: str, place: str, tmp_path: Path) -> None:
    doc = small_doc()
    iri = "https://plm.example.com/" + BAD_IRI_PARTS[kind]
    put_iri(doc, place, iri)
    error = refused(doc, tmp_path)
    assert error.pointer is not None
    assert iri in (at_pointer(doc, error.pointer), last_token(error.pointer), *(
        at_pointer(doc, error.pointer) if isinstance(at_pointer(doc, error.pointer), list) else []))
    assert "IRI" in error.message


@pytest.mark.parametrize("case", ["relative-no-base", "undefined-key", "bad-host", "bad-scheme", "language-tag",
                                  "keyword-like-key", "relative-type-no-base", "dot-segments", "base", "vocab",
                                  "floating-value", "floating-list"])
def test_what_json_ld_would_drop_silently_is_refused(case: str, tmp_path: Path) -> None:
    doc = small_doc()
    i3 = node(doc, "i3")
    if case == "relative-no-base":  # JSON-LD drops a node whose @id cannot be resolved
        doc["@graph"].append({"@context": {"@base": None}, "@id": "orphan", "https://plm.example.com/n": "x"})
        expected = "orphan"
    elif case == "undefined-key":  # a key the context does not define: JSON-LD drops its value
        i3["plm_part_number"] = "PN-4711"
        expected = "plm_part_number"
    elif case == "bad-host":
        i3["https://plm.example.com/ref"] = {"@id": "https://[::1/x"}
        expected = "https://[::1/x"
    elif case == "bad-scheme":
        i3["https://plm.example.com/ref"] = {"@id": "1https://example.com/x"}
        expected = "1https://example.com/x"
    elif case == "language-tag":
        i3["https://plm.example.com/note"] = {"@value": "x", "@language": "not a tag!"}
        expected = "not a tag!"
    elif case == "keyword-like-key":  # JSON-LD ignores a key that looks like a keyword
        i3["@partnumber"] = "PN-4711"
        expected = "@partnumber"
    elif case == "relative-type-no-base":
        doc["@graph"].append({"@context": {"@base": None}, "@id": "https://plm.example.com/x",
                              "@type": "Thing", "https://plm.example.com/n": "x"})
        expected = "Thing"
    elif case == "dot-segments":  # resolution would remove the invalid part: JSON-LD drops the node
        i3["@id"] = "a b/../c"
        expected = "a b/../c"
    elif case in ("base", "vocab"):  # resolving against an invalid base gives valid-looking IRIs
        doc["@graph"].append({"@context": {f"@{case}": "https://plm.example.com/a b/"}, "@id": "x",
                              "https://plm.example.com/n": "y"})
        expected = "https://plm.example.com/a b/"
    elif case == "floating-value":  # a value in no node: JSON-LD drops it
        doc["@graph"].append({"@value": "a note on its own"})
        expected = "a note on its own"
    else:
        doc["@graph"].append({"@list": ["a", "list", "on its own"]})
        expected = ["a", "list", "on its own"]
    error = refused(doc, tmp_path)
    assert error.pointer is not None
    found = at_pointer(doc, error.pointer)
    assert expected in (found, last_token(error.pointer), *(found.values() if isinstance(found, dict) else [])), error


@pytest.mark.parametrize("label", ["_:a b", "_:_:", "_:\u00e9t\u00e9", "_:.x", "_:x.", "_:"])
def test_any_blank_node_label_json_ld_allows_is_kept(label: str, tmp_path: Path) -> None:
    # JSON-LD takes any text after "_:"; labels only tell blank nodes apart, so one N-Triples
    # cannot write is given another (a store's bulk load would fail on it, or hang: see the report)
    doc = small_doc()
    node(doc, "i3")["https://plm.example.com/ref"] = {"@id": label, "https://plm.example.com/n": "kept"}
    node(doc, "i4")["https://plm.example.com/ref"] = {"@id": label}
    node(doc, "i4")["@type"] = ["turning_technology", label]
    path = tmp_path / "blank.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], base_iri="https://example.com/blank")
    quads = list(store.quads(r.graph))
    [blank] = {q.object for q in quads if q.predicate.value == "https://plm.example.com/ref"}
    assert isinstance(blank, ox.BlankNode)
    assert any(q.subject == blank and q.object == ox.Literal("kept") for q in quads)
    assert any(q.subject.value.endswith("/i4") and q.object == blank for q in quads  # type: ignore[union-attr]
               if q.predicate.value.endswith("#type"))


def test_a_node_whose_id_has_a_space_is_not_dropped_silently(tmp_path: Path) -> None:
    doc = small_doc()
    i3 = node(doc, "i3")
    i3["@id"] = "i 3"
    error = refused(doc, tmp_path)
    assert error.pointer == f"/@graph/{doc['@graph'].index(i3)}/@id" and "space" in error.message


@pytest.mark.parametrize("number,why", [
    ("9" * 5000, "double"), ("-" + "1" * 4400, "double"), ("123456789012345678901234", "double"),
    ("1e400", "double"), ("-1e400", "double"), ("3.14159265358979323846264338", "double"),
    ("1e99999999999999999999", "double"), ("NaN", "not a JSON number"), ("Infinity", "not a JSON number"),
    ("-Infinity", "not a JSON number"),
])
def test_numbers_json_ld_would_not_keep_are_refused_where_they_are(number: str, why: str, tmp_path: Path) -> None:
    doc = small_doc()
    node(doc, "i3")["https://plm.example.com/count"] = "NUMBER"
    text = json.dumps(doc).replace('"NUMBER"', number)
    error = refused(doc, tmp_path, text)
    assert error.pointer == f"/@graph/{doc['@graph'].index(node(doc, 'i3'))}/https:~1~1plm.example.com~1count"
    assert why in error.message and len(str(error)) < 600  # the number is shortened, not quoted whole


def test_numbers_json_ld_keeps_load_exactly(tmp_path: Path) -> None:
    doc = small_doc()
    values = {"big": "12345678901234567890", "small": "-42", "real": "0.25", "whole": "1e3", "round": "1E20"}
    for key in values:
        node(doc, "i3")[f"https://plm.example.com/{key}"] = key.upper()
    text = json.dumps(doc)
    for key, number in values.items():
        text = text.replace(f'"{key.upper()}"', number)
    path = tmp_path / "numbers.jsonld"
    path.write_text(text, encoding="utf-8")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], base_iri="https://example.com/numbers")
    got = {q.predicate.value.rsplit("/", 1)[1]: (Decimal(q.object.value), q.object.datatype.value.rsplit("#", 1)[1])
           for q in store.quads(r.graph) if q.predicate.value.startswith("https://plm.example.com/")}
    assert got == {"big": (12345678901234567890, "integer"), "small": (-42, "integer"),
                   "real": (Decimal("0.25"), "double"), "whole": (1000, "integer"), "round": (10**20, "double")}


@pytest.mark.parametrize("key,value,what", [("p21:id", "abc", "instance number"), ("p21:id", "1.5", "instance number"),
                                             ("p21:line", "x", "line number")])
def test_bookkeeping_numbers_that_are_none_are_refused_in_the_documents_terms(
        key: str, value: str, what: str, tmp_path: Path) -> None:
    doc = small_doc()
    node(doc, "i1")[key] = value
    error = refused(doc, tmp_path)
    assert f"no {what}" in error.message and error.pointer == f"/@graph/{doc['@graph'].index(node(doc, 'i1'))}/{key}"


def test_cli_reports_where_in_the_document_with_exit_2(tmp_path: Path) -> None:
    doc = small_doc()
    hostile_context("nested-array", doc, "http://127.0.0.1:9/context.jsonld")
    path = tmp_path / "hostile.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    runner = CliRunner()
    done = runner.invoke(main, ["load", "--memory", "--format", "json", str(path)])
    assert done.exit_code == 2, done.output
    [error] = json.loads(done.output)["errors"]
    assert error["type"] == "JsonLdError" and error["pointer"] == "/@context/1/0"
    assert "never fetches contexts" in error["message"]
    done = runner.invoke(main, ["load", "--memory", str(path)])
    assert done.exit_code == 2 and "hostile.jsonld at /@context/1/0: names the context" in done.output
    assert "Traceback" not in done.output


def test_a_key_given_twice_is_refused_not_read_as_the_last(tmp_path: Path) -> None:
    doc = small_doc()
    i3 = doc["@graph"].index(node(doc, "i3"))
    text = json.dumps(doc).replace('"its_id": "WS FACE"', '"its_id": "WS FACE", "its_id": "WS OTHER"')
    error = refused(doc, tmp_path, text)
    assert error.pointer == f"/@graph/{i3}" and "its_id" in error.message and "twice" in error.message


def test_a_lone_surrogate_is_refused_where_it_is(tmp_path: Path) -> None:
    doc = small_doc()
    i3 = doc["@graph"].index(node(doc, "i3"))
    text = json.dumps(doc).replace('"its_id": "WS FACE"', '"its_id": "WS \\ud800FACE"')
    error = refused(doc, tmp_path, text)
    assert error.pointer == f"/@graph/{i3}/its_id" and "surrogate" in error.message


def test_nesting_beyond_the_limit_is_refused_where_it_starts(tmp_path: Path) -> None:
    doc = small_doc()
    i3 = doc["@graph"].index(node(doc, "i3"))
    node(doc, "i3")["https://plm.example.com/deep"] = "DEEP"
    depth = MAX_DEPTH + 10
    text = json.dumps(doc).replace('"DEEP"', "[" * depth + "]" * depth)
    error = refused(doc, tmp_path, text)
    assert f"deeper than {MAX_DEPTH}" in error.message and error.pointer is not None
    assert error.pointer.startswith(f"/@graph/{i3}/https:~1~1plm.example.com~1deep/0/0")
    error = refused(doc, tmp_path, text.replace("[" * depth + "]" * depth, "[" * 100000 + "]" * 100000))
    assert f"deeper than {MAX_DEPTH}" in error.message


def test_an_overlong_id_is_refused_where_it_is(tmp_path: Path) -> None:
    """Before: a 1 MB document whose graph @id was 1 MB took 60 CPU-s (the fuzz run's input 40105):
    every quad repeats the graph's IRI."""
    from stepnc_graph.loading.jsonld import MAX_IRI

    doc = small_doc()
    doc["@id"] = "https://example.com/" + "a" * MAX_IRI
    error = refused(doc, tmp_path, json.dumps(doc))
    assert f"an @id of {len(doc['@id']):,} characters" in error.message and error.pointer == "/@id"
    i3 = doc["@graph"].index(node(doc, "i3"))
    doc = small_doc()
    node(doc, "i3")["@id"] = "https://example.com/" + "b" * MAX_IRI
    error = refused(doc, tmp_path, json.dumps(doc))
    assert error.pointer == f"/@graph/{i3}/@id"


def test_an_id_of_the_longest_length_loads(tmp_path: Path) -> None:
    from stepnc_graph.loading.jsonld import MAX_IRI

    doc = small_doc()
    doc["@id"] = "https://example.com/" + "a" * (MAX_IRI - len("https://example.com/"))
    path = tmp_path / "long.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    [r] = sg.load(sg.open_store(memory=True), [path])
    assert r.graph == doc["@id"]


def test_an_id_urllib_cannot_split_is_a_documented_error(tmp_path: Path) -> None:
    """Before: ValueError("Invalid IPv6 URL") from urljoin, a traceback (the fuzz run's input 31524)."""
    doc = small_doc()
    doc["@context"] = [doc["@context"], {"@base": "https://example.com/"}] if not isinstance(
        doc["@context"], list) else [*doc["@context"], {"@base": "https://example.com/"}]
    doc["@id"] = "http://[::1/x"
    path = tmp_path / "ipv6.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(JsonLdError, match="http://\\[::1/x"):
        sg.load(sg.open_store(memory=True), [path])


def test_nesting_within_the_limit_loads(tmp_path: Path) -> None:
    doc = small_doc()
    deep: Any = "x"
    for _ in range((MAX_DEPTH - 10) // 2):  # two levels each: the object and its array
        deep = {"@list": [deep]}
    node(doc, "i3")["https://plm.example.com/deep"] = deep
    path = tmp_path / "deep.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], base_iri="https://example.com/deep")
    assert len(list(store.quads(r.graph))) > MAX_DEPTH - 10


def test_scoped_contexts_of_a_documents_own_are_refused_before_the_processor_spends_minutes(tmp_path: Path) -> None:
    # a processor copies the active context for every term definition with a scoped context and
    # processes a scoped context again for every node using it: 2,000 such terms cost 0.5 s,
    # 8,000 (560 KB) would cost some 8 s, and the growth is quadratic
    doc = small_doc()
    doc["@context"] = [doc["@context"], {f"t{i}": {"@id": f"https://plm.example.com/t{i}",
                                                   "@context": {"a": "https://plm.example.com/a"}}
                                         for i in range(8000)}]
    started = time.process_time()
    error = refused(doc, tmp_path)
    assert time.process_time() - started < 2
    assert error.pointer == "/@context/1/t0" and "scoped context" in error.message
    # a shipped term with a scoped context of its own making is refused the same way
    doc = small_doc()
    doc["@context"]["machining_workingstep"]["@context"] = {"its_id": "stepnc:executable.its_id"}
    error = refused(doc, tmp_path)
    assert error.pointer == "/@context/machining_workingstep" and "a different one" in error.message


def test_the_shipped_context_is_named_at_the_top_only(tmp_path: Path) -> None:
    # it stands for 7,500 JSON values a processor would process again for every node naming it
    doc = small_doc()
    for n in doc["@graph"]:
        n["@context"] = CONTEXT_IRI
    started = time.process_time()
    error = refused(doc, tmp_path)
    assert time.process_time() - started < 2
    assert error.pointer is not None and re.fullmatch(r"/@graph/\d+/@context", error.pointer)
    assert "top-level @context only" in error.message
    doc = small_doc()
    doc["@context"]["machining_workingstep"]["@context"] = {"@import": CONTEXT_IRI}
    assert refused(doc, tmp_path).pointer == "/@context/machining_workingstep/@context/@import"


def test_the_shipped_context_can_be_imported_at_the_top(tmp_path: Path) -> None:
    graph, text = small_export()
    doc = json.loads(text)
    doc["@context"] = {"@import": CONTEXT_IRI, "@base": doc["@context"]["@base"],
                       "plm": "https://plm.example.com/"}
    node(doc, "i3")["plm:note"] = "kept"
    path = tmp_path / "imported.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], base_iri="https://example.com/imported")
    assert ox.Literal("kept") in {q.object for q in store.quads(r.graph)}
    assert r.instances == 6


def test_a_long_list_loads_in_linear_time(tmp_path: Path) -> None:
    # the campaign's 10^6-number @list took 581 s and 4.18 GB; 10^5 numbers took 16 s here
    doc = small_doc()
    node(doc, "i3")["https://plm.example.com/samples"] = {"@list": [1] * 100_000}
    path = tmp_path / "long.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    store = sg.open_store(memory=True)
    started = time.process_time()
    [r] = sg.load(store, [path], base_iri="https://example.com/long")
    assert time.process_time() - started < 10  # CPU seconds: 4.5 on the 2-core machine (was 14)
    assert r.triples > 200_000


# -- hostile documents, generated --------------------------------------------------------------

#: pieces of hostile text: what no IRI may hold, keyword look-alikes, escapes, long runs
NASTY_TEXT = ["\x00", " ", "\t", "\n", "<", ">", '"', "{", "}", "|", "^", "`", "\\", "%", "%zz", "%4", "/../", "./",
              "#", "?", ":", "@", "@id", "@context", "_:", "[", "]", "\u0085", "\u00a0", "\ufeff", "é", "\U0001f600",
              "http://", "file:///etc/passwd", "a" * 300]
NUMBERS = ["9" * 5000, "-" + "1" * 4301, "123456789012345678901234", "1e400", "-1e400", "1e-400", "NaN", "Infinity",
           "-Infinity", "-0", "0.1", "1e3", "12345678901234567890", "3.14159265358979323846", "1E20", "-0.0"]


@st.composite
def hostile_texts(draw: st.DrawFn) -> str:
    parts = draw(st.lists(st.one_of(st.sampled_from(NASTY_TEXT), st.text(max_size=8)), min_size=1, max_size=5))
    prefix = draw(st.sampled_from(["https://plm.example.com/", "", "_:", "stepnc:", "urn:x:", "i", "1https://"]))
    return prefix + "".join(parts)


@st.composite
def hostile_documents(draw: st.DrawFn) -> tuple[str, bool]:
    """A small program's export with hostile changes: contexts named by IRI anywhere (the
    placeholders LISTENER and FIFO become the test's loopback server and FIFO), invalid
    IRIs in every position, deep nesting, numbers JSON-LD cannot keep, long lists, duplicate
    keys; and whether to load it with --base-iri."""
    doc = small_doc()
    ctx = doc["@context"]
    numbers: list[str] = []
    duplicate = False
    for op in draw(st.lists(st.sampled_from(["context", "iri", "key", "deep", "number", "list", "twice", "base",
                                             "floating"]), min_size=1, max_size=4)):
        target = draw(st.sampled_from([n for n in doc["@graph"] if isinstance(n, dict)]))
        if op == "context":
            url = draw(st.sampled_from(["LISTENER", "FIFO", "file:///etc/passwd", CONTEXT_IRI, "https://example.com/c"]))
            value: Any = draw(st.sampled_from([url, [url], [[url]], [{}, [url]], {"@context": url}, {"@import": url},
                                               [{"ex": "https://example.com/"}, url], None, {}]))
            place = draw(st.sampled_from(["top", "node", "type-scoped", "property-scoped"]))
            if place == "top":
                doc["@context"] = [value, ctx] if draw(st.booleans()) else value
            elif place == "node":
                target["@context"] = value
            elif place == "type-scoped":
                ctx["machining_workingstep"]["@context"] = value
            else:
                scoped = ctx["machining_workingstep"].get("@context")
                if not isinstance(scoped, dict):
                    scoped = ctx["machining_workingstep"]["@context"] = {}
                scoped["its_id"] = {"@id": "stepnc:executable.its_id", "@context": value}
        elif op == "iri":
            iri = draw(hostile_texts())
            where = draw(st.sampled_from(["@id", "reference", "@type", "coerced", "datatype", "language"]))
            if where == "@id":
                target["@id"] = iri
            elif where == "reference":
                target["https://plm.example.com/ref"] = {"@id": iri}
            elif where == "@type":
                target["@type"] = [iri]
            elif where == "coerced":
                target["its_elements"] = [iri]
            elif where == "datatype":
                target["https://plm.example.com/v"] = {"@value": "1", "@type": iri}
            else:
                target["https://plm.example.com/v"] = {"@value": "x", "@language": iri}
        elif op == "key":
            target[draw(hostile_texts())] = draw(st.one_of(st.text(max_size=5), st.integers(), st.none()))
        elif op == "deep":
            depth = draw(st.sampled_from([1, 50, MAX_DEPTH // 2 - 5, MAX_DEPTH - 5, MAX_DEPTH + 5, 3000]))
            deep: Any = "x"
            for _ in range(min(depth, 900)):  # deeper ones are written as text below
                deep = [deep] if draw(st.booleans()) else {"@list": [deep]}
            target["https://plm.example.com/deep"] = deep if depth <= 900 else "DEEP"
            if depth > 900:
                numbers.append("[" * depth + "]" * depth)
        elif op == "number":
            numbers.append(draw(st.sampled_from(NUMBERS)))
            target[f"https://plm.example.com/n{len(numbers)}"] = f"NUMBER{len(numbers)}"
        elif op == "base":
            target["@context"] = {draw(st.sampled_from(["@base", "@vocab", "@language"])): draw(hostile_texts())}
        elif op == "floating":
            doc["@graph"].append(draw(st.sampled_from([{"@value": "x"}, {"@list": [1]}, {"@set": [{"@id": "i3"}]}])))
        elif op == "list":
            target["https://plm.example.com/samples"] = {"@list": draw(st.lists(
                st.one_of(st.integers(), st.floats(allow_nan=False), st.text(max_size=3), st.booleans()),
                max_size=2000))}
        else:
            duplicate = True
    text = json.dumps(doc, ensure_ascii=draw(st.booleans()))
    for i, number in enumerate(numbers, 1):
        text = text.replace(f'"NUMBER{i}"', number, 1) if not number.startswith("[") else text.replace('"DEEP"', number, 1)
    if duplicate:
        text = text.replace('"@id": "i3"', '"@id": "i3", "@id": "i4"', 1)
    return text, draw(st.booleans())


def test_hostile_documents_never_crash_connect_read_or_hang(tmp_path: Path, process_time_bound: None) -> None:
    """The promise for any JSON-LD document: a load, or a JsonLdError (exit 2) that speaks of the
    document; never a traceback, a connection, a file opened, or unbounded time; a refused load
    leaves the store as it was."""
    listener = Listener()
    fifo = FifoWatch(tmp_path / "context-fifo.jsonld")
    path = tmp_path / "generated.jsonld"
    try:
        @settings(max_examples=120, deadline=None, suppress_health_check=list(HealthCheck), database=None)
        @given(hostile_documents())
        def check(case: tuple[str, bool]) -> None:
            text, with_base = case
            path.write_text(text.replace("LISTENER", listener.url).replace("FIFO", fifo.uri), encoding="utf-8",
                            errors="surrogatepass")
            store = sg.open_store(memory=True)
            started = time.process_time()
            try:
                sg.load(store, [path], base_iri="https://example.com/generated" if with_base else None)
            except SourceError as e:  # JsonLdError, or a naming problem: both exit 2
                assert not INTERNALS.search(str(e)), str(e)
                assert listed_graphs(store) == []
            assert time.process_time() - started < 10
            assert listener.heard() == [] and fifo.opened == []

        check()
        time.sleep(0.05)
        assert listener.heard() == [] and fifo.opened == []
    finally:
        listener.close()
        fifo.close()


# -- graphs the Part 21 writer could not write back (found by the fuzz harness) ------------------

DAMAGED = ROOT / "examples" / "shaft_damaged.stp"


def _damaged_doc() -> Any:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [DAMAGED], lenient=True)
    return json.loads(sg.export(store, "jsonld", r.graph))


def _two_nodes_one_id(doc: Any) -> None:
    doc["@graph"].append({**node(doc, "i3"), "@id": "i3-copy"})


def _two_ids(doc: Any) -> None:
    node(doc, "i3")["p21:id"] = [3, 3003]


def _raw_text(value: Any) -> Any:
    def edit(doc: Any) -> None:
        node(doc, "i34")["p21:rawText"] = value
    return edit


@pytest.mark.parametrize("edit, message", [
    (_two_nodes_one_id, r"i3> and .*i3-copy> both have p21:id 3"),
    (_two_ids, r"i3> has 2 p21:id values"),
    (_raw_text("this is not Part 21"), r"i34> \(#34\): its p21:rawText is not one Part 21 instance"),
    (_raw_text("#34=A(1);\nENDSEC;\nDATA;\n#35=B(2);"), r"i34> \(#34\): its p21:rawText is not one Part 21 instance"),
    (_raw_text("#99=VENDOR_WORKINGSTEP('X');"), r"i34> has p21:id 34 but its p21:rawText defines #99"),
    (_raw_text({"@id": "https://example.com/text"}), r"i34> \(#34\) is a p21:RawInstance without one text literal"),
], ids=["two-nodes-one-id", "two-ids", "not-part21", "two-instances", "other-id", "not-a-literal"])
def test_a_graph_whose_part21_would_not_read_back_is_refused(edit: Any, message: str, tmp_path: Path) -> None:
    """Before: loaded, and its export did not parse (or the instance count broke); now refused."""
    doc = _damaged_doc()
    edit(doc)
    _refused_as_unwritable(doc, message, tmp_path)


def _refused_as_unwritable(doc: Any, message: str, tmp_path: Path) -> None:
    """Loading the edited ``doc`` is refused because its graph could not be written back as Part 21,
    and the store is left empty."""
    path = tmp_path / "edited.jsonld"
    path.write_text(json.dumps(doc), encoding="utf-8")
    store = sg.open_store(memory=True)
    with pytest.raises(JsonLdError, match="cannot be written back as Part 21: .*" + message):
        sg.load(store, [path], base_iri="https://example.com/edited")
    assert listed_graphs(store) == []


EDITION3 = ROOT / "tests" / "fixtures" / "p21" / "pass_edition3.stp"


def _set(node_id: str, key: str, value: Any) -> Any:
    def edit(doc: Any) -> None:
        node(doc, node_id)[key] = value
    return edit


@pytest.mark.parametrize("edit, message", [
    # found by the 100k fuzz run (input 18836, jsonld-list): rdf:nil for a section's text, written
    # into the file as a line "http://www.w3.org/1999/02/22-rdf-syntax-ns#nil"
    (_set("section2", "p21:sectionText", {"@list": []}), r"section2> has p21:sectionText .*nil.*not a literal"),
    (_set("section2", "p21:sectionText", "not a section"), r"does not read back as Part 21"),
    (_set("section2", "p21:sectionText", "DATA;\n#77=PROJECT('X',$,(),$,$,$);"), r"holds 1 instance\(s\) of its own"),
    (_set("https://w3id.org/stepnc-graph/data/pass_edition3.stp", "p21:anchorSectionText", "ANCHOR;\n<a>=#3;"), r"does not read back as Part 21"),
    (_set("https://w3id.org/stepnc-graph/data/pass_edition3.stp", "p21:headerText", "HEADER;\nFILE_NAME("), r"does not read back as Part 21"),
], ids=["section-iri", "section-garbage", "section-instance", "anchor-unclosed", "header-cut"])
def test_kept_header_and_section_text_that_would_not_read_back_is_refused(edit: Any, message: str,
                                                                          tmp_path: Path) -> None:
    """Before: loaded, and the export had a line that is no Part 21 (or an instance no node stands for)."""
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EDITION3])
    doc = json.loads(sg.export(store, "jsonld", r.graph))
    edit(doc)
    _refused_as_unwritable(doc, message, tmp_path)


def test_the_damaged_example_still_goes_through_json_ld_and_back(tmp_path: Path) -> None:
    """The checks above refuse nothing a lenient load of a real damaged file writes."""
    path = tmp_path / "damaged.jsonld"
    path.write_text(json.dumps(_damaged_doc()), encoding="utf-8")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path])
    assert r.instances > 0 and r.raw > 0
    assert len(list(sg.part21.read_text(sg.export(store, "p21", r.graph).decode("utf-8")).instances())) > 0
