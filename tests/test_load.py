"""Loading Part 21 into the store: mapping, diagnostics, invariant, atomicity, export, round trip."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pyoxigraph as ox
import pytest
import rdflib
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

import stepnc_graph as sg
from stepnc_graph.cli import main
from stepnc_graph.core.naming import P21_NS, STEPNC_NS
from stepnc_graph.part21 import Part21SyntaxError, read_file
from stepnc_graph.part21.diagnostics import CODES
from stepnc_graph.store import GraphStore
from stepnc_graph.testing.synth import random_program
from stepnc_graph.core.naming import listed_graphs

from conftest import FIXTURES, ROOT

P21 = FIXTURES / "p21"
EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
PASS = sorted(P21.glob("pass_*.stp")) + [EXAMPLE]
FAIL = sorted(P21.glob("fail_*.stp"))
HEADER = ("ISO-10303-21;HEADER;FILE_DESCRIPTION((''),'2;1');FILE_NAME('t','',(''),(''),'','','');"
          "FILE_SCHEMA(('MACHINING_SCHEMA','TURNING_SCHEMA'));ENDSEC;DATA;\n")


def program(tmp_path: Path, data: str, name: str = "t.stp", header: str = HEADER) -> Path:
    p = tmp_path / name
    p.write_text(header + data + "\nENDSEC;END-ISO-10303-21;\n", encoding="utf-8")
    return p


def to_rdflib(store: GraphStore, graph: str, rename: str | None = None) -> rdflib.Graph:
    """The instance triples of a graph (no file metadata, no line numbers), IRIs renamed."""
    out = rdflib.Graph()
    prefix = graph + "/"

    def conv(t: object) -> rdflib.term.Node:
        if isinstance(t, ox.BlankNode):
            return rdflib.BNode(t.value)
        if isinstance(t, ox.Literal):
            return rdflib.Literal(t.value, datatype=rdflib.URIRef(t.datatype.value))
        v = t.value  # type: ignore[attr-defined]
        return rdflib.URIRef(rename + v[len(prefix):] if rename and v.startswith(prefix) else v)

    for q in store.quads(graph):
        s = q.subject.value
        if q.predicate.value == P21_NS + "line" or s == graph or s.endswith("/load") or "/tool/" in s:
            continue
        out.add((conv(q.subject), conv(q.predicate), conv(q.object)))
    return out


def instance_ids_in_graph(store: GraphStore, graph: str) -> set[int]:
    rows = store.query(f"SELECT ?id WHERE {{ GRAPH <{graph}> {{ ?s <{P21_NS}id> ?id }} }}")
    return {int(r["id"].value) for r in rows}


# -- clean programs ----------------------------------------------------------------


@pytest.mark.parametrize("path", PASS, ids=lambda p: p.stem)
def test_pass_programs_load_cleanly_and_round_trip(path: Path, tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path])
    assert r.diagnostics == [] and r.raw == 0
    assert r.instances == sum(1 for _ in read_file(path).instances()) == len(instance_ids_in_graph(store, r.graph))
    assert_round_trip(store, r.graph, tmp_path)


def canonical(store: GraphStore, graph: str, exclude: frozenset[int] = frozenset()) -> set[str]:
    """The instance triples of a graph, IRIs made relative, blank nodes canonicalised (RDFC in Rust).

    A raw instance counts with the text the export writes (the repaired one, if any); the text of
    later definitions of an #id and unreadable text are left out (the export writes them as
    comments), and so are the
    instances numbered in ``exclude`` with what hangs off them (see :func:`unreadable_ids`).
    rdflib's isomorphism test needs minutes for a 13k-triple toolpath file; this takes milliseconds.
    """
    prefix = graph + "/"
    skip = {P21_NS + "line", P21_NS + "duplicateDefinition", P21_NS + "repairedText"}
    quads = list(store.quads(graph))
    repaired = {q.subject: q.object for q in quads if q.predicate.value == P21_NS + "repairedText"}
    dropped: set[object] = {ox.NamedNode(f"{prefix}i{i}") for i in exclude}
    dropped |= {q.object for q in quads if q.predicate.value in (P21_NS + "duplicateDefinition",
                                                                  P21_NS + "unreadableText")}
    frontier = list(dropped)
    while frontier:  # blank nodes hanging off excluded instances
        node = frontier.pop()
        for q in quads:
            if q.subject == node and isinstance(q.object, ox.BlankNode) and q.object not in dropped:
                dropped.add(q.object)
                frontier.append(q.object)

    def rename(t: object) -> object:
        if isinstance(t, ox.NamedNode) and t.value.startswith(prefix):
            return ox.NamedNode("urn:instance:" + t.value[len(prefix):])
        return t

    def effective(q: ox.Quad) -> object:
        if q.predicate.value == P21_NS + "rawText" and q.subject in repaired:
            return repaired[q.subject]
        return q.object

    ds = ox.Dataset(ox.Quad(rename(q.subject), q.predicate, rename(effective(q)))  # type: ignore[arg-type]
                    for q in quads
                    if q.predicate.value not in skip and q.subject not in dropped and q.object not in dropped and not (
                        isinstance(q.subject, ox.NamedNode) and (
                            q.subject.value == graph or q.subject.value.endswith("/load")
                            or "/tool/" in q.subject.value)))
    ds.canonicalize(ox.CanonicalizationAlgorithm.RDFC_1_0)
    return {str(q) for q in ds}


def unreadable_ids(r: sg.LoadResult) -> frozenset[int]:
    """Instances the export cannot give back as they were loaded: the unreadable ones (written as
    comments) and those referring to them (defined in the graph, undefined in the export)."""
    return frozenset(d.p21_id for d in r.diagnostics if d.p21_id is not None and (
        d.code in ("P21-SYNTAX", "P21-TRUNCATED") or "could not be read" in d.message))


def assert_round_trip(store: GraphStore, graph: str, tmp_path: Path, lenient: bool = False,
                      exclude: frozenset[int] = frozenset()) -> None:
    """Export as Part 21, which must parse strictly, load it again: the same instance graph."""
    text = sg.export(store, "p21", graph)
    out = tmp_path / "round_trip.stp"
    out.write_bytes(text)
    [r2] = sg.load(store, [out], base_iri=graph + "-rt")  # strict: an export always parses
    first, second = canonical(store, graph, exclude), canonical(store, r2.graph, exclude)
    assert len(first) > 0
    if first != second:
        pytest.fail(f"round trip differs:\n-{sorted(first - second)[:5]}\n+{sorted(second - first)[:5]}")


# -- damaged programs -----------------------------------------------------------------


def _definitions(path: Path) -> int:
    return len(re.findall(r"(?m)^\s*#\d+\s*=", path.read_text(encoding="utf-8")))


def assert_invariant(path: Path, store: GraphStore, r: sg.LoadResult) -> None:
    """Instances in the file = instances in the graph + later definitions of an #id (reported,
    their text kept on the first); unreadable instances are in the graph as their text."""
    kept = list(store.query(f"SELECT ?t WHERE {{ GRAPH <{r.graph}> {{ ?s <{P21_NS}duplicateDefinition> ?d . "
                            f"?d <{P21_NS}rawText> ?t }} }}"))
    assert _definitions(path) == len(instance_ids_in_graph(store, r.graph)) + len(kept)
    repeated = {d.p21_id for d in r.diagnostics if d.code in ("P21-DUPLICATE-ID", "P21-SYNTAX", "P21-TRUNCATED")}
    assert all(int(str(row[0].value).split("=")[0].strip().lstrip("#")) in repeated for row in kept)


@pytest.mark.parametrize("path", FAIL, ids=lambda p: p.stem)
def test_fail_programs_expected_diagnostics_and_invariant(path: Path, tmp_path: Path) -> None:
    expected = json.loads(path.with_suffix(".load.json").read_text())
    store = sg.open_store(memory=True)
    with pytest.raises(Part21SyntaxError):
        sg.load(store, [path])
    assert listed_graphs(store) == []  # strict failure: nothing loaded
    [r] = sg.load(store, [path], lenient=True)
    assert [[d.code, d.line, d.p21_id] for d in r.diagnostics] == expected["diagnostics"]
    assert (r.instances, r.raw) == (expected["instances"], expected["raw"])
    in_graph = instance_ids_in_graph(store, r.graph)
    assert_invariant(path, store, r)
    raw_ids = {int(x["id"].value) for x in store.query(
        f"SELECT ?id WHERE {{ GRAPH <{r.graph}> {{ ?s a <{P21_NS}RawInstance> ; <{P21_NS}id> ?id }} }}")}
    assert raw_ids == {d.p21_id for d in r.diagnostics if d.code in
                       ("P21-UNKNOWN-ENTITY", "P21-ARGUMENT-COUNT", "P21-VALUE-TYPE", "P21-SYNTAX", "P21-TRUNCATED") or
                       (d.code == "P21-UNRESOLVED-REF" and "not defined" in d.message)}
    assert len(in_graph) == r.instances
    assert_round_trip(store, r.graph, tmp_path, exclude=unreadable_ids(r))


CORPUS = ["EXAMPLE1_FDIS_14649-11_2001.stp", "EXAMPLE2_FDIS_14649-11_2001.stp", "EXAMPLE3_FDIS_14649-11_2001.stp",
          "nist_toolkit_ex1.stp", "nist_toolkit_ex1E.stp", "ufsc_furo.p21", "ufsc_TesteFinalUNBLAB.p21",
          "ufsc_Peca_Defesa.p21"]


@pytest.mark.shared
@pytest.mark.parametrize("name", CORPUS)
def test_corpus_loads_with_invariant_and_round_trips(shared: Path, name: str, tmp_path: Path) -> None:
    path = shared / "corpus" / "milling" / name
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], lenient=True)
    assert_invariant(path, store, r)
    assert all(d.code in ("P21-UNKNOWN-ENTITY", "P21-ARGUMENT-COUNT") for d in r.diagnostics), \
        r.diagnostics
    assert_round_trip(store, r.graph, tmp_path, exclude=unreadable_ids(r))


# -- every diagnostic code -------------------------------------------------------------

CASES = {
    "P21-SYNTAX": ("#1=PROPERTY_PARAMETER('a',,);\n#2=PROPERTY_PARAMETER('b');", True, 1),
    "P21-DUPLICATE-ID": ("#1=PROPERTY_PARAMETER('a');\n#1=PROPERTY_PARAMETER('b');", True, 1),
    "P21-CURLY-QUOTE": ("#1=PROPERTY_PARAMETER('a\u2019);\n#2=PROPERTY_PARAMETER('b');", True, 1),
    "P21-MISSING-SEMICOLON": ("#1=PROPERTY_PARAMETER('a')\n#2=PROPERTY_PARAMETER('b');", True, 1),
    "P21-BARE-ENUM": ("#1=TURNING_TECHNOLOGY($,TCP,#2,.F.,.F.,.F.);\n#2=CONST_SPINDLE_SPEED(5.);", True, 1),
    "P21-EXPRESS-REMARK": ("(* remark *)\n#1=PROPERTY_PARAMETER('a');", True, None),
    "P21-UNKNOWN-ENTITY": ("#1=NO_SUCH_THING(1);", False, 1),
    "P21-ARGUMENT-COUNT": ("#1=PROPERTY_PARAMETER('a','b');", False, 1),
    "P21-VALUE-TYPE": ("#1=PROPERTY_PARAMETER(42);", False, 1),
    "P21-VALUE-TYPE/set": ("#1=MATERIAL('s','m',(#2,#2));\n#2=PROPERTY_PARAMETER('x');", False, 1),
    "P21-ABSTRACT": ("#1=TURNING_FEATURE('f',#2,(),#3);\n#2=WORKPIECE('w',$,$,$,$,$,());\n"
                     "#3=AXIS2_PLACEMENT_3D('',#4,$,$);\n#4=CARTESIAN_POINT('',(0.,0.,0.));", False, 1),
    "P21-UNRESOLVED-REF": ("#1=CONST_CUTTING_SPEED(1.,$);\n#2=TURNING_TECHNOLOGY($,.TCP.,#9,.F.,.F.,.F.);", False, 2),
}


@pytest.mark.parametrize("code", sorted(CASES))
def test_each_diagnostic_code(code: str, tmp_path: Path) -> None:
    data, lenient, p21_id = CASES[code]
    code = code.split("/")[0]
    [r] = sg.load(sg.open_store(memory=True), [program(tmp_path, data)], lenient=lenient)
    hits = [d for d in r.diagnostics if d.code == code]
    assert hits, r.diagnostics
    assert hits[0].p21_id == p21_id and hits[0].severity == CODES[code][0]
    assert hits[0].line >= 1 and hits[0].file.endswith("t.stp")


def test_an_instance_in_another_editions_form_is_no_diagnostic(tmp_path: Path) -> None:
    """A 2002 file (FILE_SCHEMA names TURNING_SCHEMA) holding the 2001 name of explicit_strategy:
    read in that edition and reported as such, not as a problem."""
    [r] = sg.load(sg.open_store(memory=True), [program(tmp_path, "#1=EXPLICIT($,$);")])
    assert r.diagnostics == [] and r.raw == 0
    assert [(f.entity, f.edition, f.ids, f.file_has) for f in r.in_other_editions] == [
        ("EXPLICIT", "fdis2001", (1,), "no such entity")]


def test_header_and_schema_diagnostics(tmp_path: Path) -> None:
    header = "ISO-10303-21;HEADER;FILE_SCHEMA(('AP214_SCHEMA'));ENDSEC;DATA;\n"
    [r] = sg.load(sg.open_store(memory=True), [program(tmp_path, "#1=PROPERTY_PARAMETER('a');", header=header)])
    assert {d.code for d in r.diagnostics} == {"P21-HEADER", "P21-UNKNOWN-SCHEMA"}


@pytest.mark.parametrize("memory", [False, True], ids=["disk", "memory"])
def test_reference_to_a_dropped_instance_is_reported(tmp_path: Path, memory: bool) -> None:
    data = "#1=CONST_SPINDLE_SPEED(5.,,);\n#2=TURNING_TECHNOLOGY($,.TCP.,#1,.F.,.F.,.F.);"
    store = sg.open_store(tmp_path / "store", memory=memory)
    [r] = sg.load(store, [program(tmp_path, data)], lenient=True)
    assert [(d.code, d.p21_id) for d in r.diagnostics] == [("P21-SYNTAX", 1), ("P21-UNRESOLVED-REF", 2)]
    # the graph's recorded count includes the reference check made after the data was written
    [g] = sg.info(store)
    assert g.diagnostics == 2 and g.triples == r.triples == store.count(r.graph)


#: codes whose cases need a whole damaged file; their tests are in test_hostile_input.py
HOSTILE_CODES = {"P21-TRUNCATED": "test_truncated_file_loads_what_precedes_the_cut",
                 "P21-END-MISSING": "test_missing_end_marker_only_is_a_warning",
                 "P21-OUTSIDE-SECTION": "test_instance_after_endsec_is_read_into_the_section",
                 "P21-ENDSEC-MISSING": "test_a_section_without_endsec_is_closed_by_what_follows",
                 "P21-ENCODING": "test_a_latin1_byte_is_reported_and_utf8_elsewhere_is_kept"}


def test_every_code_is_tested() -> None:
    import test_hostile_input

    assert all(hasattr(test_hostile_input, name) for name in HOSTILE_CODES.values())
    tested = {c.split("/")[0] for c in CASES} | {"P21-HEADER", "P21-UNKNOWN-SCHEMA"} | set(HOSTILE_CODES)
    assert tested == set(CODES)


# -- the RDF representation ----------------------------------------------------------------


S = rdflib.Namespace(STEPNC_NS)


def load_clean(tmp_path: Path, data: str) -> tuple[GraphStore, sg.LoadResult, rdflib.Graph, rdflib.Namespace]:
    """Load ``data`` into a fresh store, require no diagnostics; the graph and the instance namespace."""
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, data)])
    assert r.diagnostics == []
    return store, r, to_rdflib(store, r.graph), rdflib.Namespace(r.graph + "/")


def test_representation(tmp_path: Path) -> None:
    data = """
#1=TURNING_TECHNOLOGY(0.2,.TCP.,#2,.T.,.F.,.F.);
#2=CONST_CUTTING_SPEED(180,$);
#3=CARTESIAN_POINT('p',(3.,1.,2.));
#4=MATERIAL('s','m',());
#5=MATERIAL('s','m',(#6,#7));
#6=PROPERTY_PARAMETER('x');
#7=PROPERTY_PARAMETER('it''s \\X2\\00E9\\X0\\');
#8=NUMERIC_PARAMETER('n',2.5,'mm');
#9=CUTTER_LOCATION_TRAJECTORY(.T.,.CONTACT.,POSITIVE_RATIO_MEASURE(0.5),$,$,$,#10,$,$);
#10=POLYLINE('',(#3,#3));
"""
    store, r, g, i = load_clean(tmp_path, data)
    X = rdflib.Namespace("http://www.w3.org/2001/XMLSchema#")
    assert (i.i1, rdflib.RDF.type, S.turning_technology) in g
    assert (i.i1, S["technology.feedrate"], rdflib.Literal("0.2", datatype=X.double)) in g
    assert (i.i1, S["technology.feedrate_reference"], S["tool_reference_point.tcp"]) in g
    assert (i.i1, S["turning_technology.spindle_speed"], i.i2) in g
    assert (i.i1, S["turning_technology.sync_spindle_and_z_feed"], rdflib.Literal(True)) in g
    assert (i.i2, S["const_cutting_speed.speed"], rdflib.Literal("180.0", datatype=X.double)) in g
    assert not list(g.objects(i.i2, S["const_cutting_speed.max_speed"]))  # $: no triple
    coords = rdflib.collection.Collection(g, g.value(i.i3, S["cartesian_point.coordinates"]))
    assert [float(x) for x in coords] == [3.0, 1.0, 2.0]  # order kept
    assert (i.i4, rdflib.URIRef(P21_NS + "emptyAggregate"), S["material.material_property"]) in g
    assert set(g.objects(i.i5, S["material.material_property"])) == {i.i6, i.i7}  # SET: repeated triples
    assert str(g.value(i.i7, S["property_parameter.parameter_name"])) == "it's \u00e9"
    assert (i.i3, rdflib.URIRef(P21_NS + "id"), rdflib.Literal(3)) in g
    typed = g.value(i.i9, S["toolpath.its_speed"])  # a typed value inside a SELECT keeps its type
    assert isinstance(typed, rdflib.BNode)
    assert (typed, rdflib.RDF.type, S.positive_ratio_measure) in g
    assert g.value(typed, rdflib.URIRef(P21_NS + "value")) == rdflib.Literal("0.5", datatype=X.double)
    assert_round_trip(store, r.graph, tmp_path)


def test_complex_instance_and_derived_marker(tmp_path: Path) -> None:
    data = ("#1=(PROPERTY_PARAMETER('a')MATERIAL('s','m',()));\n"
            "#2=PROPERTY_PARAMETER(*);")
    store, r, g, i = load_clean(tmp_path, data)
    assert {S.property_parameter, S.material} <= set(g.objects(i.i1, rdflib.RDF.type))
    assert (i.i2, rdflib.URIRef(P21_NS + "derivedValue"), S["property_parameter.parameter_name"]) in g
    assert_round_trip(store, r.graph, tmp_path)


def test_raw_instance_keeps_source_text(tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, "#7=CONST_SURFACE_SPEED(2.5,10);")])
    raw = list(store.query(f"SELECT ?t ?n WHERE {{ GRAPH <{r.graph}> {{ ?s <{P21_NS}rawText> ?t ; "
                           f"<{P21_NS}entityName> ?n }} }}"))
    assert [(x["t"].value, x["n"].value) for x in raw] == [("#7=CONST_SURFACE_SPEED(2.5,10);", "CONST_SURFACE_SPEED")]
    assert b"#7=CONST_SURFACE_SPEED(2.5,10);" in sg.export(store, "p21", r.graph)


# -- IRIs, graphs, metadata ------------------------------------------------------------------


def test_stable_iris_and_named_graph_metadata(tmp_path: Path) -> None:
    a = program(tmp_path, "#5=PROPERTY_PARAMETER('a');", "a.stp")
    b = program(tmp_path, "#5=PROPERTY_PARAMETER('a');", "b.stp")
    store = sg.open_store(memory=True)
    [ra] = sg.load(store, [a])
    assert ra.graph == "https://w3id.org/stepnc-graph/data/a.stp"
    [rb] = sg.load(store, [b], base_iri="https://plm.example.org/parts/42")
    assert rb.graph == "https://plm.example.org/parts/42"
    assert instance_ids_in_graph(store, rb.graph) == {5}
    assert bool(store.query(f"ASK {{ GRAPH <{rb.graph}> {{ <{rb.graph}/i5> ?p ?o }} }}"))
    meta = {row["p"].value.rsplit("/", 1)[-1].rsplit("#", 1)[-1]: row["o"].value for row in store.query(
        f"SELECT ?p ?o WHERE {{ GRAPH <{ra.graph}> {{ <{ra.graph}> ?p ?o }} }}")}
    assert meta["sha256"] == __import__("hashlib").sha256(a.read_bytes()).hexdigest()
    assert meta["byteSize"] == str(a.stat().st_size)
    assert meta["schemaName"] in ("MACHINING_SCHEMA", "TURNING_SCHEMA")
    assert meta["headerText"].startswith("HEADER;") and meta["headerText"].endswith("ENDSEC;")
    assert {"generatedAtTime", "wasGeneratedBy", "source", "instanceCount"} <= set(meta)


def test_edition3_structure_in_the_graph_and_back(tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [P21 / "pass_edition3.stp"])
    g = r.graph

    def rows(variables: str, query: str) -> set[tuple[str, ...]]:
        return {tuple(t.value.replace(g, "") for t in row) for row in store.query(
            f"PREFIX p21: <{P21_NS}> SELECT {variables} WHERE {{ GRAPH <{g}> {{ {query} }} }}")}

    assert rows("?i ?a", "?i p21:anchorName ?a") == {("/i3", "face_step"), ("/i5", "origin")}
    assert rows("?i ?u", "?i p21:externalReference ?u") == {("/i900", "library.stp#spindle_800")}
    assert rows("?i ?s ?n", "?i p21:dataSection ?s . ?s p21:sectionIndex ?n") == {
        ("/i1", "/section1", "1"), ("/i2", "/section1", "1"), ("/i3", "/section1", "1"), ("/i4", "/section1", "1"),
        ("/i5", "/section2", "2"), ("/i6", "/section2", "2")}
    [(signature,)] = rows("?t", "?g p21:signatureText ?t")
    assert signature.startswith("SIGNATURE")
    text = sg.export(store, "p21", g).decode()
    assert "SIGNATURE" not in text  # it signs the original bytes, which the export does not reproduce
    assert text.index("ANCHOR;") < text.index("REFERENCE;") < text.index("DATA('process'") < text.index(
        "#4=") < text.index("DATA('geometry'") < text.index("#5=")
    # a one-section file records no sections
    [r1] = sg.load(store, [EXAMPLE])
    assert not bool(store.query(f"ASK {{ GRAPH <{r1.graph}> {{ ?i <{P21_NS}dataSection> ?s }} }}"))


def test_sections_on_one_line_are_kept(tmp_path: Path) -> None:
    """Section openers need not start a line: a file written on one line keeps its two sections."""
    one_line = HEADER.replace("DATA;\n", "") + ("DATA('a',('TURNING_SCHEMA'));#1=PROPERTY_PARAMETER('x');ENDSEC;"
                                               "DATA('b',('TURNING_SCHEMA'));#2=PROPERTY_PARAMETER('y');ENDSEC;"
                                               "END-ISO-10303-21;")
    path = tmp_path / "one_line.stp"
    path.write_text(one_line, encoding="utf-8")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path])
    text = sg.export(store, "p21", r.graph).decode()
    assert text.index("DATA('a'") < text.index("#1=") < text.index("DATA('b'") < text.index("#2=")
    assert_round_trip(store, r.graph, tmp_path)


def test_edition3_value_names_keep_the_instance_raw(tmp_path: Path) -> None:
    data = "#1=CONST_SPINDLE_SPEED(@7);\n#2=CONST_SPINDLE_SPEED(800.);"
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, data)])
    [d] = r.diagnostics
    assert (d.code, d.p21_id) == ("P21-VALUE-TYPE", 1) and "@7" in d.message and "outside the file" in d.message
    assert r.raw == 1 and "#1=CONST_SPINDLE_SPEED(@7);" in sg.export(store, "p21", r.graph).decode()


OWL_SAME_AS = "http://www.w3.org/2002/07/owl#sameAs"


def test_its_id_aliases_for_plm_links(tmp_path: Path) -> None:
    data = ("#1=PROPERTY_PARAMETER('x');\n"
            "#2=WORKPLAN('MAIN / PLAN',(),$,$,$);\n"  # executable.its_id, unique: aliased
            "#3=WORKPLAN('TWICE',(),$,$,$);\n#4=WORKPLAN('TWICE',(),$,$,$);\n"  # shared: no alias
            "#5=WORKPLAN('',(),$,$,$);\n"  # empty: no alias
            "#6=WORKPIECE('TWICE',$,$,$,$,$,());\n"  # other scope: its own alias
            "#7=WORKPLAN('BROKEN',(),$,$);")  # raw (argument count): no alias
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, data)])
    g = r.graph
    aliases = {row["a"].value[len(g):]: row["i"].value[len(g):] for row in store.query(
        f"SELECT ?a ?i WHERE {{ GRAPH <{g}> {{ ?a <{OWL_SAME_AS}> ?i }} }}")}
    assert aliases == {"/id/executable/MAIN%20%2F%20PLAN": "/i2", "/id/workpiece/TWICE": "/i6"}
    # the aliases are not instances: the file written back is the same program
    assert_round_trip(store, g, tmp_path)
    assert "sameAs" not in sg.export(store, "p21", g).decode()


def test_reload_is_idempotent_and_unload(tmp_path: Path) -> None:
    store = sg.open_store(tmp_path / "store")
    [r1] = sg.load(store, [EXAMPLE])
    count = store.count(r1.graph)
    [r2] = sg.load(store, [EXAMPLE])
    assert listed_graphs(store) == [r1.graph] and store.count(r1.graph) == count == r2.triples
    assert sg.unload(store, r1.graph) is True and listed_graphs(store) == []
    assert sg.unload(store, r1.graph) is False


# -- atomicity -----------------------------------------------------------------------------------


def _snapshot(store: GraphStore) -> list[str]:
    return sorted(str(q) for q in store.quads())


@pytest.mark.parametrize("memory", [False, True], ids=["disk", "memory"])
def test_failure_mid_load_leaves_store_unchanged(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 memory: bool) -> None:
    store = sg.open_store(None if memory else tmp_path / "store", memory=memory)
    sg.load(store, [EXAMPLE])
    before = _snapshot(store)
    from stepnc_graph.mapping import mapper

    calls = {"n": 0}
    original = mapper.InstanceMapper.map

    def failing(self, inst, out):  # type: ignore[no-untyped-def]
        calls["n"] += 1
        if calls["n"] == 50:
            raise RuntimeError("injected failure")
        return original(self, inst, out)

    monkeypatch.setattr(mapper.InstanceMapper, "map", failing)
    monkeypatch.setattr(sys.modules["stepnc_graph.loading.loader"], "CHUNK_LINES", 10)  # some data reaches the store
    with pytest.raises(RuntimeError, match="injected"):
        sg.load(store, [EXAMPLE])
    assert _snapshot(store) == before
    if not memory:
        store.close()
        assert not (tmp_path / "store" / "work.dirty").exists()


def test_strict_syntax_error_late_in_file_leaves_store_unchanged(tmp_path: Path) -> None:
    store = sg.open_store(tmp_path / "store")
    sg.load(store, [EXAMPLE])
    before = _snapshot(store)
    damaged = tmp_path / "shaft_two_setups.stp"  # same name: would replace the graph
    damaged.write_text(EXAMPLE.read_text().replace("#292=DIRECTION('-Z',(0.,0.,-1.));", "#292=DIRECTION('-Z',(0.,,);"))
    with pytest.raises(Part21SyntaxError):
        sg.load(store, [damaged], replace=True)
    assert _snapshot(store) == before


def test_killed_load_is_rolled_back_on_next_open(tmp_path: Path) -> None:
    store_dir = tmp_path / "store"
    store = sg.open_store(store_dir)
    sg.load(store, [EXAMPLE])
    before = _snapshot(store)
    store.close()
    script = f"""
import os, stepnc_graph as sg, stepnc_graph.loading.loader
from stepnc_graph.mapping import mapper
import sys
sys.modules['stepnc_graph.loading.loader'].CHUNK_LINES = 10
original = mapper.InstanceMapper.map
count = [0]
def dying(self, inst, out):
    count[0] += 1
    if count[0] == 60:
        os._exit(9)  # like kill -9: no cleanup runs
    return original(self, inst, out)
mapper.InstanceMapper.map = dying
sg.load(sg.open_store({str(store_dir)!r}), [{str(EXAMPLE)!r}])
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 9, done.stderr
    assert (store_dir / "work.dirty").exists()  # the interrupted load left work/ marked
    assert _snapshot(sg.open_store(store_dir, readonly=True)) == before  # readers never saw it
    reopened = sg.open_store(store_dir, readonly=False)  # the next writer recovers
    assert _snapshot(reopened) == before
    assert not (store_dir / "work.dirty").exists()


# -- export ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("fmt,parser", [("ttl", "turtle"), ("nt", "nt"), ("nq", "nquads"), ("trig", "trig"),
                                        ("jsonld", "json-ld")])
def test_exports_parse_back(fmt: str, parser: str) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EXAMPLE])
    data = sg.export(store, fmt, None if fmt in ("nq", "trig") else r.graph)
    ds = rdflib.Dataset()
    ds.parse(data=data.decode("utf-8"), format=parser)
    total = sum(len(g) for g in ds.graphs())
    # without --graph nq/trig hold the loaded graphs: the file's (not its derived layer or the vocabulary)
    assert total == store.count(r.graph)
    if fmt == "jsonld":
        assert json.loads(data)["@context"]["stepnc"] == STEPNC_NS


class _CountingStore:
    """A pyoxigraph store that counts the calls made to it (what an export costs in round trips)."""

    def __init__(self, db: ox.Store) -> None:
        self.db = db
        self.calls = 0

    def __getattr__(self, name: str) -> object:
        attribute = getattr(self.db, name)
        if not callable(attribute):
            return attribute

        def counted(*args: object, **kwargs: object) -> object:
            self.calls += 1
            return attribute(*args, **kwargs)
        return counted


@pytest.mark.parametrize("fmt", ["nt", "ttl", "nq", "jsonld"])
def test_an_export_reads_each_graph_in_one_call(fmt: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """The canonical order is made from one read of each graph, not from a call into the store
    per subject (which made an export of a 100k-instance program cost more than its load)."""
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EXAMPLE])
    expected = sg.export(store, fmt, None if fmt == "nq" else r.graph)
    counting = _CountingStore(store.oxigraph)
    monkeypatch.setattr(GraphStore, "oxigraph", property(lambda self: counting))
    assert sg.export(store, fmt, None if fmt == "nq" else r.graph) == expected
    graphs = len(store.all_graphs())  # program, derived layer, vocabulary
    assert counting.calls <= (graphs + 1 if fmt == "nq" else 1), counting.calls


def test_an_export_keeps_unicode_line_separators_inside_literals(tmp_path: Path) -> None:
    """U+2028, U+2029 and U+0085 end a line for Python's ``splitlines`` but not for N-Triples,
    which leaves them unescaped: the export's text-based ordering must not split a triple there."""
    path = program(tmp_path, "#1=PROPERTY_PARAMETER('a\\X2\\2028\\X0\\b\\X2\\2029\\X0\\c\\X2\\0085\\X0\\d');")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path])
    assert not r.diagnostics
    for fmt in ("nt", "nq"):
        data = sg.export(store, fmt, r.graph if fmt == "nt" else None)
        values = {str(q.object.value) for q in ox.parse(data, ox.RdfFormat.N_QUADS)
                  if q.predicate.value == STEPNC_NS + "property_parameter.parameter_name"}
        assert values == {"a\u2028b\u2029c\u0085d"}


def test_export_needs_a_graph_when_several(tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE, program(tmp_path, "#1=PROPERTY_PARAMETER('a');")])
    from stepnc_graph.exporting.exporter import ExportError

    with pytest.raises(ExportError, match="choose one"):
        sg.export(store, "ttl")


# -- property-based round trip --------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(st.integers(min_value=0, max_value=10**6))
def test_random_schema_valid_programs_load_cleanly_and_round_trip(seed: int) -> None:
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"random_{seed}.stp"
        path.write_text(random_program(seed), encoding="utf-8")
        store = sg.open_store(memory=True)
        [r] = sg.load(store, [path])
        assert r.diagnostics == [], r.diagnostics[:3]
        assert_round_trip(store, r.graph, Path(d))
        # and the exported text reads back to the same parameters
        exported = Path(d) / "exported.stp"
        exported.write_bytes(sg.export(store, "p21", r.graph))
        original = {i.id: _norm_instance(i) for i in read_file(path).instances()}
        again = {i.id: _norm_instance(i) for i in read_file(exported).instances()}
        assert original == again


def _norm_instance(inst: object) -> tuple[str, list[object]]:
    """An instance's name and parameters; numbers as floats, SET members in sorted order."""
    from stepnc_graph.mapping.plans import iso14649_plans

    plan = iso14649_plans().entities[inst.name]  # type: ignore[attr-defined]
    params = [_norm(v) for v in inst.params]  # type: ignore[attr-defined]
    for slot in plan.slots:
        if slot.repeated and isinstance(params[slot.index], list):
            params[slot.index] = sorted(params[slot.index], key=repr)  # type: ignore[arg-type]
    return inst.name, params  # type: ignore[attr-defined]


def _norm(value: object) -> object:
    if isinstance(value, list):
        return [_norm(v) for v in value]
    if type(value) in (int, float):
        return float(value)  # type: ignore[arg-type]
    return repr(value)


# -- CLI ------------------------------------------------------------------------------------------------


def test_cli_load_json_and_exit_codes(tmp_path: Path) -> None:
    runner = CliRunner()
    store = str(tmp_path / "store")
    ok = runner.invoke(main, ["load", "--store", store, str(EXAMPLE), "--format", "json"])
    assert ok.exit_code == 0, ok.output
    doc = json.loads(ok.output)
    f = doc["files"][0]
    assert set(f) >= {"path", "graph", "instances", "triples", "diagnostics"} and f["instances"] == 89
    damaged = runner.invoke(main, ["load", "--store", store, "--lenient", "--format", "json", str(FAIL[0])])
    assert damaged.exit_code == 1
    d = json.loads(damaged.output)["files"][0]["diagnostics"][0]
    assert set(d) == {"code", "severity", "line", "column", "p21_id", "message"}
    strict = runner.invoke(main, ["load", "--store", store, str(FAIL[0])])
    assert strict.exit_code == 2
    info = runner.invoke(main, ["info", "--store", store, "--format", "json"])
    assert len(json.loads(info.output)["graphs"]) == 2
    out = tmp_path / "x.stp"
    exported = runner.invoke(main, ["export", "--store", store, "--graph",
                                    "https://w3id.org/stepnc-graph/data/shaft_two_setups.stp", "--format", "p21",
                                    "-o", str(out)])
    assert exported.exit_code == 0 and out.read_text().startswith("ISO-10303-21;")
    assert runner.invoke(main, ["export", "--store", store, "--format", "ttl"]).exit_code == 2  # two graphs
    gone = runner.invoke(main, ["unload", "--store", store, "https://w3id.org/stepnc-graph/data/shaft_two_setups.stp"])
    assert gone.exit_code == 0
    assert runner.invoke(main, ["unload", "--store", store, "urn:nope"]).exit_code == 2  # like export --graph


def test_store_env_var_and_not_a_store(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("STEPNC_GRAPH_STORE", str(tmp_path / "envstore"))
    res = CliRunner().invoke(main, ["load", str(EXAMPLE)])
    assert res.exit_code == 0 and (tmp_path / "envstore" / "CURRENT").is_file()
    other = tmp_path / "other"
    other.mkdir()
    (other / "precious.txt").write_text("x")
    res = CliRunner().invoke(main, ["info", "--store", str(other)])
    assert res.exit_code == 2 and "not a stepnc-graph store" in res.output


def test_rdflib_view_of_the_store() -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [EXAMPLE])
    ds = store.rdflib_dataset()
    g = ds.graph(rdflib.URIRef(r.graph))
    assert len(g) == store.count(r.graph)
