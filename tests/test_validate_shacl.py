"""The engine as a general SHACL validator: any RDF data, shapes nobody here wrote, the defects of
issue 28 one by one (each test failed on the engine before it was rebuilt on components)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from rdflib import SH, Graph, Literal, URIRef

from stepnc_graph.validation import DataError, ShapesError, UnsupportedShapes, validate

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
PREFIXES = """@prefix sh: <http://www.w3.org/ns/shacl#> . @prefix ex: <http://example.org/> .
@prefix xsd: <http://www.w3.org/2001/XMLSchema#> . @prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
@prefix stepnc: <https://w3id.org/stepnc-graph/iso14649#> .
"""


def _files(tmp_path: Path, data: str, shapes: str, suffix: str = ".ttl") -> tuple[Path, Path]:
    d, s = tmp_path / f"data{suffix}", tmp_path / "shapes.ttl"
    d.write_text((PREFIXES if suffix == ".ttl" else "") + data)
    s.write_text(PREFIXES + shapes)
    return d, s


def _check(tmp_path: Path, data: str, shapes: str, suffix: str = ".ttl") -> Any:
    d, s = _files(tmp_path, data, shapes, suffix)
    return validate([d], extra_shapes=[s], iso_shapes=False)


def _cli(*args: str) -> Any:
    from click.testing import CliRunner

    from stepnc_graph.cli import main

    return CliRunner().invoke(main, list(args))


def test_a_turtle_file_is_validated_from_the_command_line(tmp_path: Path) -> None:
    d, s = _files(tmp_path, "ex:a a ex:Person ; ex:age -3 . ex:b a ex:Person ; ex:age 30 .",
                  "ex:P a sh:NodeShape ; sh:targetClass ex:Person ; "
                  "sh:property [ sh:path ex:age ; sh:minInclusive 0 ; sh:datatype xsd:integer ] .")
    res = _cli("validate", str(d), "--shapes", str(s), "--no-iso-shapes", "--format", "json")
    assert res.exit_code == 1, res.output
    doc = json.loads(res.output)
    assert doc["conforms"] is False and doc["passes"] is False
    assert [(r["focus"], r["path"], r["value"]) for r in doc["results"]] == [("http://example.org/a", "age", "-3")]
    text = _cli("validate", str(d), "--shapes", str(s), "--no-iso-shapes")
    assert "a  age: must be >= 0, found -3" in text.output  # a node that is no Part 21 instance is named
    assert _cli("validate", str(d), "--no-iso-shapes").exit_code == 2  # no shapes at all


@pytest.mark.parametrize("suffix,data", [
    (".nt", "<http://example.org/a> <http://example.org/age> \"-3\"^^<http://www.w3.org/2001/XMLSchema#integer> .\n"),
    (".nq", "<http://example.org/a> <http://example.org/age> \"-3\"^^<http://www.w3.org/2001/XMLSchema#integer> <http://example.org/g> .\n"),
    (".trig", "<http://example.org/g> { <http://example.org/a> <http://example.org/age> -3 }\n"),
])
def test_other_rdf_formats(tmp_path: Path, suffix: str, data: str) -> None:
    report = _check(tmp_path, data, "ex:P sh:targetSubjectsOf ex:age ; sh:property [ sh:path ex:age ; sh:minInclusive 0 ] .",
                    suffix)
    assert [(r.focus, r.value) for r in report.results] == [("http://example.org/a", "-3")]


def test_rdf_data_that_does_not_parse_is_bad_input(tmp_path: Path) -> None:
    d, s = _files(tmp_path, "ex:a ex:p .", "ex:P sh:targetNode ex:a .")
    with pytest.raises(DataError, match=r"data\.ttl"):
        validate([d], extra_shapes=[s], iso_shapes=False)
    assert _cli("validate", str(d), "--shapes", str(s), "--no-iso-shapes").exit_code == 2


def test_closed_shape_on_the_shipped_example(tmp_path: Path) -> None:
    """sh:closed was accepted and never evaluated: a closed shape pySHACL rejects conformed."""
    rule = tmp_path / "closed.ttl"
    rule.write_text(PREFIXES + "ex:C a sh:NodeShape ; sh:targetClass stepnc:project ; sh:closed true ; "
                    "sh:ignoredProperties ( <http://www.w3.org/1999/02/22-rdf-syntax-ns#type> ) ; "
                    "sh:property [ sh:path stepnc:project.its_id ] .")
    import pyoxigraph as ox
    import pyshacl

    from stepnc_graph import api

    report = validate([EXAMPLE], extra_shapes=[rule])
    mine = {(r.focus, r.path_iri, r.value_term) for r in report.results if r.shape == "http://example.org/C"}
    with api.open_store(memory=True) as store:
        [loaded] = api.load(store, [EXAMPLE])
        data = Graph().parse(data=store.dump(ox.RdfFormat.N_TRIPLES, loaded.graph).decode(), format="nt")
    _, theirs_graph, _ = pyshacl.validate(data, shacl_graph=Graph().parse(rule), inference="none")
    theirs = {(str(theirs_graph.value(x, SH.focusNode)), f"<{theirs_graph.value(x, SH.resultPath)}>",
               theirs_graph.value(x, SH.value).n3()) for x in theirs_graph.objects(None, SH.result)}
    assert mine and mine == theirs
    assert _cli("validate", str(EXAMPLE), "--shapes", str(rule)).exit_code == 1


def test_recursive_shapes_are_refused_with_the_cycle(tmp_path: Path) -> None:
    with pytest.raises(UnsupportedShapes, match=r"recursive.*ex/B> -> .*ex/A> -> .*ex/B>"):
        _check(tmp_path, "ex:a ex:knows ex:b .",
               "ex:A sh:targetNode ex:a ; sh:property [ sh:path ex:knows ; sh:node ex:B ] . "
               "ex:B sh:property [ sh:path ex:knows ; sh:node ex:A ] .".replace("ex:A", "<http://example.org/ex/A>")
               .replace("ex:B", "<http://example.org/ex/B>"))
    d, s = _files(tmp_path, "ex:a ex:knows ex:b .", "ex:A sh:targetNode ex:a ; sh:node ex:A .")
    res = _cli("validate", str(d), "--shapes", str(s), "--no-iso-shapes")
    assert res.exit_code == 2 and "recursive" in res.output and "Traceback" not in res.output


def test_blank_nodes_given_a_class_in_data_and_shapes(tmp_path: Path) -> None:
    report = _check(tmp_path, "_:x a ex:Thing ; ex:size -1 . ex:a ex:part _:x .",
                    "[] a ex:Thing . ex:S sh:targetClass ex:Thing ; sh:property [ sh:path ex:size ; sh:minInclusive 0 ] . "
                    "ex:T sh:targetNode ex:a ; sh:property [ sh:path ex:part ; sh:class ex:Thing ] .")
    assert [(r.component.rsplit("#", 1)[1], r.value) for r in report.results] == [("MinInclusiveConstraintComponent", "-1")]


def test_a_custom_severity(tmp_path: Path) -> None:
    report = _check(tmp_path, "ex:a ex:p 1 .", "ex:S sh:targetNode ex:a ; sh:severity ex:Blocker ; "
                    "sh:property [ sh:path ex:p ; sh:maxInclusive 0 ; sh:severity ex:Blocker ] .")
    [r] = report.results
    assert r.severity == "http://example.org/Blocker" and not report.passes and not report.conforms
    assert "sh:resultSeverity <http://example.org/Blocker>" in report.to_turtle()


def test_your_own_message_is_shown_with_its_variables_and_languages(tmp_path: Path) -> None:
    report = _check(tmp_path, "ex:a ex:p 5 .",
                    "ex:S sh:targetNode ex:a ; sh:property [ sh:path ex:p ; sh:maxInclusive 3 ; "
                    "sh:message \"too big: {$value}\"@en, \"trop grand : {?value}\"@fr ] . "
                    "ex:Q sh:targetNode ex:a ; sh:sparql [ sh:select \"SELECT $this ?v WHERE { $this ex:p ?v }\" ; "
                    "sh:prefixes ex:P ; sh:message \"p is {?v}\" ] . ex:P sh:declare [ sh:prefix \"ex\" ; "
                    "sh:namespace \"http://example.org/\"^^xsd:anyURI ] .")
    by_shape = {r.shape: r for r in report.results}
    assert by_shape["http://example.org/Q"].message == "p is 5"
    [own] = [r for r in report.results if r.shape is None]
    assert own.message == "too big: 5" and set(own.message_terms) == {'"too big: 5"@en', '"trop grand : 5"@fr'}
    ttl = Graph().parse(data=report.to_turtle(), format="turtle")
    assert Literal("trop grand : 5", lang="fr") in set(ttl.objects(None, SH.resultMessage))


def test_type_triples_in_the_shapes_file_are_not_data(tmp_path: Path) -> None:
    report = _check(tmp_path, "ex:a ex:p 1 .", "ex:x a ex:C . ex:S sh:targetClass ex:C ; sh:property [ sh:path ex:q ; "
                    "sh:minCount 1 ] .")
    assert report.conforms and not report.results


def test_subclasses_in_the_data_graph_count(tmp_path: Path) -> None:
    report = _check(tmp_path, "ex:Dog rdfs:subClassOf ex:Animal . ex:rex a ex:Dog . ex:bob ex:pet ex:rex , ex:stone .",
                    "ex:A sh:targetClass ex:Animal ; sh:property [ sh:path ex:name ; sh:minCount 1 ] . "
                    "ex:B sh:targetSubjectsOf ex:pet ; sh:property [ sh:path ex:pet ; sh:class ex:Animal ] .")
    assert sorted((r.focus, r.component.rsplit("#", 1)[1], r.value) for r in report.results) == [
        ("http://example.org/bob", "ClassConstraintComponent", "http://example.org/stone"),
        ("http://example.org/rex", "MinCountConstraintComponent", None)]


def test_integer_subtypes_and_ill_typed_literals(tmp_path: Path) -> None:
    """xsd:int values pass sh:datatype xsd:int (Oxigraph stores them as xsd:integer), an xsd:integer
    does not, and an ill-typed literal fails and is reported when the file is read."""
    report = _check(tmp_path, 'ex:a ex:i "5"^^xsd:int ; ex:j 7 ; ex:k "abc"^^xsd:integer ; ex:b "300"^^xsd:byte .',
                    "ex:S sh:targetNode ex:a ; sh:property [ sh:path ex:i ; sh:datatype xsd:int ] , "
                    "[ sh:path ex:j ; sh:datatype xsd:int ] , [ sh:path ex:k ; sh:datatype xsd:integer ] , "
                    "[ sh:path ex:b ; sh:datatype xsd:byte ] .")
    got = sorted((r.component.rsplit("#", 1)[-1].split(":")[-1], r.path) for r in report.results)
    assert got == [("DatatypeConstraintComponent", "b"), ("DatatypeConstraintComponent", "j"),
                   ("DatatypeConstraintComponent", "k"), ("RDF-ILL-TYPED", "b"), ("RDF-ILL-TYPED", "k")]


def test_a_relative_iri_in_a_shapes_file_uses_the_file_as_base(tmp_path: Path) -> None:
    d, s = _files(tmp_path, "ex:a ex:p 1 .", "<#S> sh:targetNode ex:a ; sh:property [ sh:path ex:q ; sh:minCount 1 ] .")
    [r] = validate([d], extra_shapes=[s], iso_shapes=False).results
    assert r.focus == "http://example.org/a"
    assert _cli("validate", str(d), "--shapes", str(s), "--no-iso-shapes").exit_code == 1


def test_warnings_only_pass_but_do_not_conform(tmp_path: Path) -> None:
    d, s = _files(tmp_path, "ex:a ex:p 1 .", "ex:S sh:targetNode ex:a ; sh:severity sh:Warning ; "
                  "sh:property [ sh:path ex:q ; sh:minCount 1 ; sh:severity sh:Warning ] .")
    res = _cli("validate", str(d), "--shapes", str(s), "--no-iso-shapes", "--format", "turtle")
    assert res.exit_code == 0  # the exit code's rule: warnings do not fail
    g = Graph().parse(data=res.output, format="turtle")
    assert Literal(False) in set(g.objects(None, SH.conforms))  # SHACL's: any result


def test_unsupported_shacl_is_refused_not_skipped(tmp_path: Path) -> None:
    with pytest.raises(UnsupportedShapes, match="sh:rule"):
        _check(tmp_path, "ex:a ex:p 1 .", "ex:S sh:targetNode ex:a ; sh:rule [ a sh:TripleRule ] .")
    with pytest.raises(ShapesError, match="MINUS"):
        _check(tmp_path, "ex:a ex:p 1 .", "ex:S sh:targetNode ex:a ; sh:sparql [ sh:select "
               "\"SELECT $this WHERE { $this ?p ?o MINUS { $this ?p 1 } }\" ] .")


def test_a_json_ld_file_is_validated(tmp_path: Path) -> None:
    d = tmp_path / "data.jsonld"
    d.write_text(json.dumps({"@context": {"ex": "http://example.org/"}, "@id": "ex:a", "ex:age": -3}))
    s = tmp_path / "shapes.ttl"
    s.write_text(PREFIXES + "ex:P sh:targetSubjectsOf ex:age ; sh:property [ sh:path ex:age ; sh:minInclusive 0 ] .")
    report = validate([d], extra_shapes=[s], iso_shapes=False)
    assert [(r.focus, r.value) for r in report.results if not r.component.startswith("loader:")] == [
        ("http://example.org/a", "-3")]


def test_turtle_report_paths_are_rdf(tmp_path: Path) -> None:
    report = _check(tmp_path, "ex:a ex:p ex:b . ex:b ex:q 5 .",
                    "ex:S sh:targetNode ex:a ; sh:property [ sh:path ( ex:p ex:q ) ; sh:maxInclusive 1 ] .")
    g = Graph().parse(data=report.to_turtle(), format="turtle")
    [path] = g.objects(None, SH.resultPath)
    assert list(g.items(path)) == [URIRef("http://example.org/p"), URIRef("http://example.org/q")]
