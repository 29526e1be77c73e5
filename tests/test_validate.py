"""The validator: pySHACL (the reference) finds the same results on every fixture; expected findings."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pyoxigraph as ox
import pytest
from rdflib import RDF, SH, BNode, Graph, URIRef
from rdflib.collection import Collection

from stepnc_graph import api
from stepnc_graph.validation import shape_files, validate

ROOT = Path(__file__).resolve().parent.parent
FIX = Path(__file__).parent / "fixtures"
VFIX = FIX / "validate"
PROGRAMS = [ROOT / "examples" / "shaft_two_setups.stp", *sorted((FIX / "p21").glob("*_seed_annex_*.stp")),
            *sorted(VFIX.glob("*.stp"))]

Key = tuple[str, str | None, str, str, str | None]


def _path_text(g: Graph, node: Any) -> str:
    """A SHACL path as SPARQL path text, the way stepnc-graph's engine writes it."""
    if isinstance(node, URIRef):
        return f"<{node}>"
    if (node, RDF.first, None) in g:
        return "(" + "/".join(_path_text(g, x) for x in Collection(g, node)) + ")"
    for kind, fmt in ((SH.inversePath, "^{}"), (SH.zeroOrMorePath, "{}*"), (SH.oneOrMorePath, "{}+"),
                      (SH.zeroOrOnePath, "{}?")):
        inner = g.value(node, kind)
        if inner is not None:
            return "(" + fmt.format(_path_text(g, inner)) + ")"
    return "(" + "|".join(_path_text(g, x) for x in Collection(g, g.value(node, SH.alternativePath))) + ")"


def _focus(term: Any) -> str:
    return "_:blank" if isinstance(term, BNode) or str(term).startswith("_:") else str(term)


def reference(program: Path) -> tuple[set[Key], set[Key]]:
    """(pySHACL's results, stepnc-graph's results) on the same shapes and data, as comparable keys."""
    import pyshacl

    files = shape_files()
    with api.open_store(memory=True) as store:
        [loaded] = api.load(store, [program], lenient=True)
        data = Graph().parse(data=store.dump(ox.RdfFormat.N_TRIPLES, loaded.graph).decode(), format="nt")
        ours = validate(store, graphs=[loaded.graph])
    data.parse(ROOT / "shapes" / "support.ttl")
    shapes = Graph()
    for f in files:
        if f.name != "support.ttl":
            shapes.parse(f)
    _, report, _ = pyshacl.validate(data, shacl_graph=shapes, inference="none", advanced=False)
    theirs: set[Key] = set()
    for r in report.objects(None, SH.result):  # top-level results (sh:detail holds nested ones)
        path = report.value(r, SH.resultPath)
        shape = report.value(r, SH.sourceShape)
        theirs.add((_focus(report.value(r, SH.focusNode)), _path_text(report, path) if path is not None else None,
                    str(report.value(r, SH.sourceConstraintComponent)), str(report.value(r, SH.resultSeverity)),
                    str(shape) if isinstance(shape, URIRef) else None))
    mine: set[Key] = set()
    for res in ours.results:
        if res.component.startswith("loader:"):
            continue
        path = res.path_iri
        mine.add((_focus(res.focus), path, res.component, f"{SH}{res.severity}", res.shape))
    return theirs, mine


@pytest.mark.parametrize("program", PROGRAMS, ids=lambda p: p.name)
def test_same_results_as_pyshacl(program: Path) -> None:
    theirs, mine = reference(program)
    assert mine == theirs, {"only pySHACL": theirs - mine, "only stepnc-graph": mine - theirs}


def test_example_and_corrected_annex_d_conform() -> None:
    report = validate([ROOT / "examples" / "shaft_two_setups.stp", FIX / "p21" / "pass_seed_annex_d.stp"])
    assert report.passes and not report.conforms, report.to_text()  # a warning: passes, but SHACL's conforms is false
    # the one finding is a warning: the example's relief groove (#42) is roughed (#34) and never finished
    assert [(r.graph.rsplit("/", 1)[-1], r.p21_id, r.severity, r.value) for r in report.results] == [
        ("shaft_two_setups.stp", 34, "Warning", "#42 GROOVE")]


def test_the_corrected_plan_passes_every_process_rule() -> None:
    """pass_plan.stp is fail_plan.stp corrected (tools that fit, at the width limit; rough before
    finish; the groove finished; Annex C values in range): no result at all."""
    fail = {r.shape for r in validate([VFIX / "fail_plan.stp"]).results}
    assert len({s for s in fail if s and "process-" in s}) == 9  # what the failing twin breaks
    report = validate([VFIX / "pass_plan.stp"])
    assert report.conforms and report.passes and not report.results, report.to_text()


def test_corrected_annex_e_has_zero_corner_radii() -> None:
    """The corrected Annex E program still gives two SQUARE_U_PROFILEs corner radii of 0, which
    positive_length_measure (theoretical_size of toleranced_length_measure) forbids: found, not hidden."""
    report = validate([FIX / "p21" / "pass_seed_annex_e.stp"])
    assert [(r.p21_id, r.path, r.value) for r in report.results] == [
        (234, "theoretical_size", "0"), (235, "theoretical_size", "0"),
        (244, "theoretical_size", "0"), (245, "theoretical_size", "0")]


@pytest.mark.parametrize("program", sorted(VFIX.glob("fail_*.stp")), ids=lambda p: p.name)
def test_expected_findings(program: Path) -> None:
    """Each fail_ fixture lists its findings: #id, attribute path and shape (or loader code)."""
    want = json.loads(program.with_suffix(".expected.json").read_text())
    report = validate([program])
    got = [{"p21_id": r.p21_id, "path": r.path, "shape": (r.shape or r.component).rsplit("#", 1)[-1],
            "severity": r.severity} for r in report.results]
    assert got == want["results"], report.to_text()
    assert report.passes is want["conforms"]  # the fixtures' "conforms": no violation (the exit code)


def _cli(*args: str) -> Any:
    from click.testing import CliRunner

    from stepnc_graph.cli import main

    return CliRunner().invoke(main, list(args))


def test_cli_exit_codes_and_formats(tmp_path: Path) -> None:
    example = str(ROOT / "examples" / "shaft_two_setups.stp")
    failing = str(VFIX / "fail_shapes.stp")
    assert _cli("validate", example).exit_code == 0
    res = _cli("validate", "--format", "json", failing)
    assert res.exit_code == 1
    doc = json.loads(res.output)
    assert doc["conforms"] is False and {"severity", "p21_id", "entity", "line", "path", "value", "message", "rule",
                                          "clause", "focus"} <= set(doc["results"][0])
    ttl = _cli("validate", "--format", "turtle", failing)
    report = Graph().parse(data=ttl.output, format="turtle")
    assert len(list(report.objects(None, SH.result))) == len(doc["results"])
    assert _cli("validate").exit_code == 2  # neither files nor a store
    bad = tmp_path / "bad.ttl"
    bad.write_text("this is not turtle")
    assert _cli("validate", "--shapes", str(bad), example).exit_code == 2
    broken = tmp_path / "broken.stp"
    broken.write_text("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n#1=PROJECT('x' ;\nENDSEC;\nEND-ISO-10303-21;\n")
    assert _cli("validate", "--strict", str(broken)).exit_code == 2
    assert _cli("validate", str(broken)).exit_code == 1  # lenient: the syntax error is a result


def test_extra_shapes_and_store_mode(tmp_path: Path) -> None:
    """An organisation's own rule (--shapes) runs beside the shipped ones; a store is validated in place."""
    rule = tmp_path / "org.ttl"
    rule.write_text("""@prefix sh: <http://www.w3.org/ns/shacl#> . @prefix stepnc: <https://w3id.org/stepnc-graph/iso14649#> .
<urn:org:feed> a sh:NodeShape ; sh:targetClass stepnc:technology ;
  sh:property [ sh:path stepnc:technology.feedrate ; sh:maxInclusive 0.2 ; sh:severity sh:Warning ] .""")
    with api.open_store(tmp_path / "store") as store:
        api.load(store, [ROOT / "examples" / "shaft_two_setups.stp"])
        report = validate(store, extra_shapes=[rule])
    assert report.passes and not report.conforms  # warnings do not fail a program; SHACL's conforms is false
    assert [(r.p21_id, r.severity, r.value) for r in report.results] == [(34, "Warning", "#42 GROOVE"),
                                                                       (70, "Warning", "0.25")]
    assert _cli("validate", "--store", str(tmp_path / "store"), "--shapes", str(rule),
                "--severity", "violation").output.count("line") == 0


def test_oneof_on_a_complex_instance(tmp_path: Path) -> None:
    """ONEOF checks are skipped only while no instance has two types: a complex instance is checked."""
    text = (ROOT / "examples" / "shaft_two_setups.stp").read_text()
    end = text.rindex("ENDSEC;")
    program = tmp_path / "complex.stp"
    program.write_text(text[:end] + "#400=(CARTESIAN_POINT((0.,0.,0.))DIRECTION('D',(0.,0.,1.))"
                       "GEOMETRIC_REPRESENTATION_ITEM()POINT('P')REPRESENTATION_ITEM());\n" + text[end:])
    theirs, mine = reference(program)
    assert mine == theirs
    assert any(key[0].endswith("/i400") and "oneof" in (key[4] or "") for key in mine)


# -- checks the Part 21 mapping implies (stepnc_graph.validation.implied) -----------------------------


def _implied_checks() -> list[Any]:
    from stepnc_graph.validation import compile_shapes

    return [c for c in compile_shapes(shape_files()).checks if c.implied is not None]


@pytest.mark.parametrize("program", PROGRAMS, ids=lambda p: p.name)
def test_checks_the_mapping_implies_find_nothing_on_what_it_wrote(program: Path) -> None:
    """The cross-check: every check a file's validation skips, run anyway on every fixture (damaged
    ones included) finds nothing; and the file's report equals the store's, which skips nothing."""
    from stepnc_graph.validation import _implied_skips
    from stepnc_graph.validation.runner import run

    with api.open_store(memory=True) as store:
        [loaded] = api.load(store, [program], lenient=True)
        skipped = _implied_skips(store.oxigraph, loaded)
        rows, ran = run(store.oxigraph, loaded.graph, [c for c in _implied_checks() if c.implied in skipped])
        assert ran > 0 and rows == []
        from_store = validate(store, graphs=[loaded.graph])
    from_file = validate([program], lenient=True)
    assert from_file.checks_run < from_store.checks_run
    def shapes_results(report: Any) -> list[dict[str, Any]]:  # loader diagnostics reach a store's report otherwise
        return [r.asdict() for r in report.results if not r.component.startswith("loader:")]

    assert shapes_results(from_file) == shapes_results(from_store)


def test_what_the_mapping_implies_and_what_it_does_not() -> None:
    implied = {(c.shape.rsplit("#", 1)[-1][:-1], c.constraint, c.argument): c.implied for c in _implied_checks()}
    assert implied[("point.name", "maxCount", '"1"^^<http://www.w3.org/2001/XMLSchema#integer>')] == "always"
    assert implied[("point.name", "datatype", "<http://www.w3.org/2001/XMLSchema#string>")] == "always"
    members = {arg.rsplit("#", 1)[-1][:-1]: v for (shape, constraint, arg), v in implied.items()
               if shape == "cartesian_point.coordinates" and constraint == "node"}
    assert members == {"cartesian_point.coordinates-list": "no-unset-members",  # LIST [1:3] OF length_measure
                       "ListMin1": "list-bounds", "ListMax3": "list-bounds"}
    assert implied[("point.name", "minCount", '"1"^^<http://www.w3.org/2001/XMLSchema#integer>')] == "mandatory-set"
    assert not any(c == "class" for _, c, _ in implied)  # references: the data decides
    assert not any(shape == "manufacturing_feature.its_operations" for shape, _, _ in implied)  # a SET of refs


def test_an_unset_list_member_is_still_checked(tmp_path: Path) -> None:
    """A `$` inside a list is written p21:unset, which the members' datatype rejects: the file's
    validation then runs the members checks too."""
    program = _with_instance(tmp_path, "unset_member.stp", "#400=CARTESIAN_POINT('P',(0.,$,1.));")
    report = validate([program], lenient=True)
    assert any(r.p21_id == 400 and r.path == "coordinates" for r in report.results), report.to_text()
    theirs, mine = reference(program)
    assert mine == theirs


def _with_instance(tmp_path: Path, name: str, instance: str) -> Path:
    text = (ROOT / "examples" / "shaft_two_setups.stp").read_text()
    end = text.rindex("ENDSEC;")
    program = tmp_path / name
    program.write_text(text[:end] + instance + "\n" + text[end:])
    return program


def test_a_list_out_of_its_bounds_is_still_checked(tmp_path: Path) -> None:
    """The mapper counts list lengths against their bounds: one list out of them, and the file's
    validation runs the length checks (and finds it, as pySHACL does)."""
    program = _with_instance(tmp_path, "four_coordinates.stp", "#400=CARTESIAN_POINT('P',(0.,0.,1.,2.));")
    [loaded] = api.load(api.open_store(memory=True), [program])
    assert not loaded.lists_within_bounds
    assert api.load(api.open_store(memory=True), [ROOT / "examples" / "shaft_two_setups.stp"])[0].lists_within_bounds
    report = validate([program])
    assert [(r.p21_id, r.path, r.shape.rsplit("#", 1)[-1]) for r in report.results if r.p21_id == 400] == [
        (400, "coordinates", "cartesian_point.coordinates")]
    theirs, mine = reference(program)
    assert mine == theirs


def test_a_class_below_a_topological_and_a_geometric_item_conforms(tmp_path: Path) -> None:
    """vertex_point is below geometric_representation_item and topological_representation_item,
    as ISO 10303-42 has it (no ONEOF on representation_item separates them): a correct instance
    has no ONEOF violation, here and in pySHACL."""
    program = _with_instance(tmp_path, "vertex_point.stp", "#400=CARTESIAN_POINT('P',(0.,0.,1.));\n"
                                                           "#401=VERTEX_POINT('V',#400);")
    report = validate([program])
    assert not any(r.p21_id == 401 and "oneof" in (r.shape or "") for r in report.results), report.to_text()
    theirs, mine = reference(program)
    assert mine == theirs


def test_an_unset_mandatory_attribute_is_still_checked(tmp_path: Path) -> None:
    """`$` for a mandatory attribute: the mapper notes it, and the file's validation runs the
    minCount checks (and finds it, as pySHACL does)."""
    program = _with_instance(tmp_path, "unset_name.stp", "#400=CARTESIAN_POINT($,(0.,0.,1.));")
    [loaded] = api.load(api.open_store(memory=True), [program])
    assert not loaded.mandatory_values_set
    report = validate([program])
    assert [(r.p21_id, r.path) for r in report.results if r.p21_id == 400] == [(400, "name")], report.to_text()
    theirs, mine = reference(program)
    assert mine == theirs


def test_large_input_is_validated_in_a_temporary_store_on_disk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Above MEMORY_VALIDATION_BYTES the throw-away store is on disk (bounded memory at 1M instances):
    the same report, and nothing left behind."""
    import importlib
    import tempfile

    module = importlib.import_module("stepnc_graph.validation.throwaway")
    program = VFIX / "fail_plan.stp"
    in_memory = validate([program])
    monkeypatch.setattr(module, "MEMORY_VALIDATION_BYTES", 0)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    opened: list[Any] = []
    stores = importlib.import_module("stepnc_graph.store")  # where validation opens its throw-away store
    real = stores.open_store

    def spy(*args: Any, **kwargs: Any) -> Any:
        opened.append((args, kwargs))
        return real(*args, **kwargs)

    monkeypatch.setattr(stores, "open_store", spy)
    on_disk = validate([program])
    assert opened and not opened[0][1].get("memory") and str(opened[0][0][0]).startswith(str(tmp_path))
    assert [r.asdict() for r in on_disk.results] == [r.asdict() for r in in_memory.results]
    assert list(tmp_path.iterdir()) == []


# -- a file's throw-away graph: positions from the load, checks on threads ---------------------------


def test_a_load_without_position_triples_gives_the_same_positions_and_diagnostics(tmp_path: Path) -> None:
    """``positions=False`` writes no p21:id/p21:line and returns each instance's line instead; the
    reference check against unreadable instances (which reads positions) finds the same referrers,
    direct and through a list."""
    program = tmp_path / "p.stp"
    program.write_text(
        "ISO-10303-21;HEADER;FILE_DESCRIPTION((''),'2;1');FILE_NAME('t','',(''),(''),'','','');"
        "FILE_SCHEMA(('MACHINING_SCHEMA','TURNING_SCHEMA'));ENDSEC;DATA;\n"
        "#1=CONST_SPINDLE_SPEED(5.,,);\n#2=TURNING_TECHNOLOGY($,.TCP.,#1,.F.,.F.,.F.);\n"
        "#3=CARTESIAN_POINT('p',(0.,0.,0.));\n#4=POLYLINE('l',(#3,#1));\nENDSEC;END-ISO-10303-21;\n")
    p21 = "https://w3id.org/stepnc-graph/p21#"
    with api.open_store(memory=True) as full, api.open_store(memory=True) as slim:
        [a] = api.load(full, [program], lenient=True)
        [b] = api.load(slim, [program], lenient=True, positions=False)
        lines = {int(q.subject.value.rsplit("/i", 1)[1]): int(q.object.value)
                 for q in full.quads(a.graph) if q.predicate.value == p21 + "line"
                 and isinstance(q.subject, ox.NamedNode)}
        assert a.lines is None and b.lines == lines == {1: 2, 2: 3, 3: 4, 4: 5}
        assert not [q for q in slim.quads(b.graph) if q.predicate.value in (p21 + "id", p21 + "line")]
        assert b.triples == a.triples - 2 * len(lines)
        assert [d.asdict() for d in b.diagnostics] == [d.asdict() for d in a.diagnostics]
        assert [(d.code, d.p21_id) for d in b.diagnostics] == [
            ("P21-SYNTAX", 1), ("P21-UNRESOLVED-REF", 2), ("P21-UNRESOLVED-REF", 4)]


def test_a_check_that_reads_positions_keeps_them(tmp_path: Path) -> None:
    """An organisation's rule may read p21:line: then validate FILE loads the position triples."""
    rule = tmp_path / "org.ttl"
    rule.write_text("""@prefix sh: <http://www.w3.org/ns/shacl#> . @prefix stepnc: <https://w3id.org/stepnc-graph/iso14649#> .
<urn:org:late> a sh:NodeShape ; sh:targetClass stepnc:technology ; sh:severity sh:Warning ;
  sh:sparql [ sh:select "SELECT $this ?value WHERE { $this <https://w3id.org/stepnc-graph/p21#line> ?value FILTER(?value > 51) }" ] .""")
    example = ROOT / "examples" / "shaft_two_setups.stp"
    with api.open_store(memory=True) as store:
        [loaded] = api.load(store, [example])
        expected = sorted((r.p21_id, r.value) for r in validate(store, extra_shapes=[rule]).results
                          if r.shape == "urn:org:late")
    assert expected  # the rule finds something on the example...
    found = sorted((r.p21_id, r.value) for r in validate([example], extra_shapes=[rule]).results
                   if r.shape == "urn:org:late")
    assert found == expected  # ... and the same in a file's throw-away graph


def test_checks_on_threads_give_their_rows_in_check_order(monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib

    from stepnc_graph.validation import compile_shapes

    engine = importlib.import_module("stepnc_graph.validation.runner")
    checks = list(compile_shapes(shape_files()).checks)
    with api.open_store(memory=True) as store:
        [loaded] = api.load(store, [FIX / "p21" / "fail_seed_annex_d.stp"], lenient=True)
        runs = []
        for threads in (1, 3):
            monkeypatch.setattr(engine, "CHECK_THREADS", threads)
            rows, ran = engine.run(store.oxigraph, loaded.graph, checks)
            runs.append([(r.check.shape, r.check.constraint, str(r.focus), str(r.value)) for r in rows])
    assert len(runs[0]) >= 5 and runs[0] == runs[1]


def test_oneof_checks_are_skipped_where_no_node_can_fail_them() -> None:
    """An sh:not of classes (ONEOF) runs only on a graph with a node of two types or of a class below
    both sides: on the example, none of the ONEOF checks runs (they are a tenth of the checks)."""
    import pyoxigraph as ox  # noqa: F401

    from stepnc_graph.validation import compile_shapes
    from stepnc_graph.validation.runner import run

    shipped = compile_shapes(shape_files())
    oneof = [c for c in shipped.checks if c.constraint == "not" and "oneof" in c.shape]
    assert len(oneof) > 50 and all(c.excludes is not None for c in oneof)
    with api.open_store(memory=True) as store:
        [loaded] = api.load(store, [ROOT / "examples" / "shaft_two_setups.stp"], derived=False)
        _, ran = run(store.oxigraph, loaded.graph, oneof, frozenset(), shipped.hierarchy)
    assert ran == 0


def test_the_shipped_checks_leave_the_position_triples_out() -> None:
    """No shipped check reads p21:id/p21:line or any predicate: validate FILE loads without them (a
    sixth fewer triples). A SELECT's projection of three variables is no triple pattern."""
    from stepnc_graph.validation import compile_shapes
    from stepnc_graph.validation.reads import reads_positions

    assert not reads_positions(compile_shapes(shape_files()).checks)


def test_a_loader_warning_keeps_its_severity_and_does_not_fail_the_program(tmp_path: Path) -> None:
    """A program whose only finding is a loader warning (an EXPRESS remark between instances,
    skipped) passes: the result is a Warning, as the loader said, not a Violation; an error stays
    a Violation."""
    clean = ROOT / "examples" / "shaft_two_setups.stp"
    text = clean.read_text()
    first = text.index("\n#") + 1
    remarked = tmp_path / "remarked.stp"
    remarked.write_text(text[:first] + "(* a remark the loader skips *)\n" + text[first:])
    before = {(r.p21_id, r.severity, r.value) for r in validate([clean]).results}
    report = validate([remarked])
    loader = [(r.component, r.severity) for r in report.results if r.component.startswith("loader:")]
    assert loader == [("loader:P21-EXPRESS-REMARK", "Warning")], report.to_text()
    assert {(r.p21_id, r.severity, r.value) for r in report.results if not r.component.startswith("loader:")} == before
    assert report.passes and _cli("validate", str(remarked)).exit_code == 0
    turtle = Graph().parse(data=_cli("validate", "--format", "turtle", str(remarked)).output, format="turtle")
    assert set(turtle.objects(None, SH.resultSeverity)) == {SH.Warning}
    unknown = tmp_path / "unknown.stp"
    unknown.write_text(text[:first] + "#99999=NO_SUCH_ENTITY(1);\n" + text[first:])
    assert ("loader:P21-UNKNOWN-ENTITY", "Violation") in {(r.component, r.severity) for r in validate([unknown]).results}
