"""The WHERE rules of the 2001 edition: found where they differ from 2002 by comparing each entity's
rules across the two editions, compiled from the 2001 EXPRESS against the terms the loader writes,
and applied to the instances read in that edition only (a 2002 instance keeps the 2002 rule)."""

from __future__ import annotations

from pathlib import Path

import pyoxigraph as ox
import pytest

import stepnc_graph.api as sg
from stepnc_graph.generators.edition_shapes import comparable_text, rule_differences
from stepnc_graph.mapping.editions import RENAMED
from stepnc_graph.schema.catalog import load_catalog_model, load_edition_model

from conftest import ROOT

FIXTURES = ROOT / "tests" / "fixtures" / "editions"
BALL_2001 = FIXTURES / "ball_endmills_fdis2001.stp"
BALL_2002 = FIXTURES / "ball_endmills_2002.stp"
PLATE = FIXTURES / "plate_fdis2001.stp"
SHAPES = "https://w3id.org/stepnc-graph/shapes#"


@pytest.fixture(scope="module")
def differences():  # type: ignore[no-untyped-def]
    _, own = load_edition_model("fdis2001")
    _, shipped = load_catalog_model()
    return own, shipped, rule_differences(own, shipped, RENAMED["fdis2001"])


def test_rules_that_differ_between_2001_and_2002_are_found_by_comparing_them(differences) -> None:  # type: ignore[no-untyped-def]
    own, shipped, found = differences
    assert [(d.entity, d.shipped_entity, d.label, d.kind) for d in found] == [
        ("back_boring", "back_boring", "WR1", "edition only"),
        ("ball_endmill", "ball_endmill", "WR4", "differs"),  # tool_top_angle / tool_tip_half_angle
        ("bullnose_endmill", "bullnose_endmill", "WR1", "differs"),
        ("definitional_representation", "definitional_representation", "WR1", "edition only"),
        ("milling_machining_operation", "milling_machining_operation", "WR1", "edition only"),
        ("trimmed_curve", "trimmed_curve", "WR1", "differs"),  # 2001: trim_1[1] twice; 2002: [1] or [2]
        ("trimmed_curve", "trimmed_curve", "WR2", "differs"),
        ("trimmed_curve", "trimmed_curve", "WR3", "edition only"),
    ]
    ball = {d.label: d for d in found if d.entity == "ball_endmill"}
    assert "tool_top_angle" in (ball["WR4"].edition_text or "") and "tool_tip_half_angle" in (ball["WR4"].shipped_text or "")


def test_what_does_not_change_a_rule_is_set_aside(differences) -> None:  # type: ignore[no-untyped-def]
    """2001 ball_endmill WR2 says SELF.dimension.diameter where 2002 says dimension.diameter (the
    same attribute of SELF); a TYPEOF string's schema prefix names each edition's own schema."""
    own, shipped, _ = differences
    [wr2_2001] = [r for r in own.entities["ball_endmill"].where_rules if r.label.upper() == "WR2"]
    [wr2_2002] = [r for r in shipped.entities["ball_endmill"].where_rules if r.label.upper() == "WR2"]
    assert "SELF.dimension.diameter" in wr2_2001.source.replace(" ", "") and "SELF.dimension.diameter" not in wr2_2002.source.replace(" ", "")
    assert comparable_text(wr2_2001.expr) == comparable_text(wr2_2002.expr)


def _marks() -> list[tuple[str, str, str]]:
    store = ox.Store()
    store.load(path=str(ROOT / "shapes" / "edition_fdis2001.ttl"), format=ox.RdfFormat.TURTLE)
    out = []
    for name in ("edition", "notForEdition", "replaces"):
        for q in store.quads_for_pattern(None, ox.NamedNode(SHAPES + name), None, None):
            obj = q.object.value.removeprefix(SHAPES)
            out.append((q.subject.value.removeprefix(SHAPES), name, obj))  # type: ignore[union-attr]
    return sorted(out)


def test_the_2001_rules_are_shapes_of_their_own_and_the_2002_ones_they_differ_from_are_marked() -> None:
    assert _marks() == [
        ("ball_endmill-wr4", "notForEdition", "fdis2001"),
        ("bullnose_endmill-wr1", "notForEdition", "fdis2001"),
        ("fdis2001.back_boring-wr1", "edition", "fdis2001"),
        ("fdis2001.ball_endmill-wr4", "edition", "fdis2001"),
        ("fdis2001.ball_endmill-wr4", "replaces", "ball_endmill-wr4"),
        ("fdis2001.bullnose_endmill-wr1", "edition", "fdis2001"),
        ("fdis2001.bullnose_endmill-wr1", "replaces", "bullnose_endmill-wr1"),
        ("fdis2001.milling_machining_operation-wr1", "edition", "fdis2001"),
        ("fdis2001.trimmed_curve-wr3", "edition", "fdis2001"),  # its evident intent (a schema defect)
    ]
    text = (ROOT / "shapes" / "edition_fdis2001.ttl").read_text(encoding="utf-8")
    # compiled against the terms the 2001 loader writes: the shared body, the edition's own angle
    assert "#milling_machine_tool_body.dimension>/<https://w3id.org/stepnc-graph/iso14649#tool_dimension.tool_top_angle>" in text


def _findings(path: Path) -> list[tuple[int | None, str | None, str]]:
    return [(r.p21_id, r.rule, r.message.split(":", 1)[0]) for r in sg.validate([path]).results]


def test_a_2001_ball_endmill_is_checked_by_the_2001_rules_at_its_id() -> None:
    """#20 gives tool_top_angle 15 (2001 WR4: 0) and edge_center_vertical 4 for diameter 10 (WR2:
    5); #21 keeps both."""
    report = sg.validate([BALL_2001])
    found = [(r.p21_id, r.rule.split(":")[0] if r.rule else None, r.shape) for r in report.results]
    assert found == [(10, "ball_endmill WR2", SHAPES + "ball_endmill-wr2"), (10, "ball_endmill WR4", SHAPES + "fdis2001.ball_endmill-wr4")]
    wr4 = report.results[1]
    assert "tool_top_angle" in wr4.message and wr4.clause is not None and "2001" in wr4.clause


def test_the_same_data_as_a_2002_file_gets_the_2002_rules() -> None:
    report = sg.validate([BALL_2002])
    assert [(r.p21_id, r.rule.split(":")[0] if r.rule else None, r.shape) for r in report.results] == [
        (10, "ball_endmill WR2", SHAPES + "ball_endmill-wr2"), (10, "ball_endmill WR4", SHAPES + "ball_endmill-wr4")]
    assert "tool_tip_half_angle" in report.results[1].message


def test_a_2001_rule_2002_lacks_is_applied_to_2001_programs(tmp_path: Path) -> None:
    """2001 milling_machining_operation WR1: a feed per tooth needs a tool with a number of teeth."""
    assert sg.validate([PLATE]).results == []
    wrong = tmp_path / "plate_feed_per_tooth.stp"
    wrong.write_text(PLATE.read_text()
                     .replace("#16=MILLING_TECHNOLOGY(0.05,.TCP.,$,25.,$,", "#16=MILLING_TECHNOLOGY($,.TCP.,$,25.,0.01,")
                     .replace("#50=CENTER_DRILL(#52,2,", "#50=CENTER_DRILL(#52,$,"))
    assert [(r.p21_id, r.rule.split(":")[0] if r.rule else None, r.shape) for r in sg.validate([wrong]).results] == [
        (12, "milling_machining_operation WR1", SHAPES + "fdis2001.milling_machining_operation-wr1")]


def test_a_store_holding_both_editions_checks_each_by_its_own(tmp_path: Path) -> None:
    store = sg.open_store(tmp_path / "store")
    sg.load(store, [BALL_2001, BALL_2002])
    found = sorted((r.graph.rsplit("/", 1)[-1], r.p21_id, r.shape) for r in sg.validate(store).results)
    store.close()
    assert found == [
        ("ball_endmills_2002.stp", 10, SHAPES + "ball_endmill-wr2"),
        ("ball_endmills_2002.stp", 10, SHAPES + "ball_endmill-wr4"),
        ("ball_endmills_fdis2001.stp", 10, SHAPES + "ball_endmill-wr2"),
        ("ball_endmills_fdis2001.stp", 10, SHAPES + "fdis2001.ball_endmill-wr4"),
    ]


def test_ontology_stats_lists_each_edition_rule_and_what_checks_it() -> None:
    """`ontology stats` lists per edition the rules that differ from 2002: the shape that checks
    each on the edition's instances (the ones in shapes/edition_fdis2001.ttl), or why none does."""
    import json

    from click.testing import CliRunner

    from stepnc_graph.cli import main

    result = CliRunner().invoke(main, ["ontology", "stats", "--format", "json"])
    assert result.exit_code == 0, result.output
    rows = json.loads(result.output)["edition_rules"]
    assert [(r["edition"], r["rule"], r["kind"], r["shape"], r["shipped_rule_withheld"]) for r in rows] == [
        ("fdis2001", "back_boring.wr1", "edition only", "shapes:fdis2001.back_boring-wr1", False),
        ("fdis2001", "ball_endmill.wr4", "differs", "shapes:fdis2001.ball_endmill-wr4", True),
        ("fdis2001", "bullnose_endmill.wr1", "differs", "shapes:fdis2001.bullnose_endmill-wr1", True),
        ("fdis2001", "definitional_representation.wr1", "edition only", None, False),
        ("fdis2001", "milling_machining_operation.wr1", "edition only",
         "shapes:fdis2001.milling_machining_operation-wr1", False),
        ("fdis2001", "trimmed_curve.wr1", "differs", None, False),
        ("fdis2001", "trimmed_curve.wr2", "differs", None, False),
        ("fdis2001", "trimmed_curve.wr3", "edition only", "shapes:fdis2001.trimmed_curve-wr3", False)]
    reasons = {r["rule"]: r["reason"] for r in rows if r["reason"]}
    never = "schema defect: as written it is FALSE for every instance: TYPEOF gives only the names of types the " \
            "schemas declare (and built-in ones), '{}' names none of them, and the rule admits nothing else; "
    assert reasons == {
        "definitional_representation.wr1": never.format("parametric_representation_context")
        + "no evident intent to check instead",
        "trimmed_curve.wr1": "TYPEOF test for parameter_value, which is not an entity",
        "trimmed_curve.wr2": "TYPEOF test for parameter_value, which is not an entity",
        "trimmed_curve.wr3": never.format("parameter") + "its evident intent checked: master_representation is "
                                                         ".PARAMETER."}
    shipped = (ROOT / "shapes" / "edition_fdis2001.ttl").read_text()
    assert all((r["shape"].removeprefix("shapes:") + "\n") in shipped for r in rows if r["shape"])
    text = CliRunner().invoke(main, ["ontology", "stats"]).output
    assert "WHERE rules of edition fdis2001 that differ from 2002: 8, 5 translated (shapes/edition_fdis2001.ttl)" in text
    assert ("  ball_endmill.wr4 (differs): checked by shapes:fdis2001.ball_endmill-wr4; the 2002 rule is not "
            "applied to its instances") in text


def test_a_users_own_shapes_say_that_2001_instances_were_checked_by_them_only(tmp_path: Path) -> None:
    """--no-iso-shapes --shapes X without shapes/edition_fdis2001.ttl: the 2001 instances are checked
    by X's rules (here the 2002 milling tool rules, whose WR4 a 2001 ball end mill does not break)
    and the report says so, in text, JSON and Turtle; with the edition file among the shapes, or
    with the ISO shapes in use, the 2001 rule finds #10 and there is nothing to note."""
    import json

    from click.testing import CliRunner
    from rdflib import RDFS, Graph

    from stepnc_graph.cli import main

    mine = tmp_path / "our_tool_rules.ttl"
    shipped = (ROOT / "shapes" / "milling_tool_schema.ttl").read_text()
    mine.write_text(shipped.replace(SHAPES, "https://example.org/our-shapes#"))  # ours, beside the shipped ones
    assert mine.read_text() != shipped
    edition_file = ROOT / "shapes" / "edition_fdis2001.ttl"
    report = sg.validate([BALL_2001], iso_shapes=False, extra_shapes=[mine])
    graph = "https://w3id.org/stepnc-graph/data/ball_endmills_fdis2001.stp"
    assert report.notes == [
        f"{graph}: the instances of edition fdis2001 were checked by the given shapes only, not by that edition's own "
        "WHERE rules (shapes/edition_fdis2001.ttl, part of the ISO 14649 shapes, is not among them)"]
    assert not any(r.rule and r.rule.startswith("ball_endmill WR4") for r in report.results)
    assert report.to_text().splitlines()[-1] == "note: " + report.notes[0]
    assert json.loads(report.to_json())["notes"] == report.notes
    turtle = Graph().parse(data=report.to_turtle(), format="turtle")
    assert [str(o) for o in turtle.objects(None, RDFS.comment)] == report.notes
    cli = CliRunner().invoke(main, ["validate", "--no-iso-shapes", "--shapes", str(mine), "--format", "json",
                                    str(BALL_2001)])
    assert json.loads(cli.output)["notes"] == report.notes
    for checked in (sg.validate([BALL_2001], iso_shapes=False, extra_shapes=[mine, edition_file]),
                    sg.validate([BALL_2001], extra_shapes=[mine])):
        assert checked.notes == []
        assert [r.p21_id for r in checked.results if r.rule and r.rule.startswith("ball_endmill WR4")] == [10]
    assert sg.validate([BALL_2002], iso_shapes=False, extra_shapes=[mine]).notes == []
    mixed = sg.validate([FIXTURES / "plate_fdis2001_mixed.stp"], edition="2002", iso_shapes=False,
                        extra_shapes=[mine])
    # read as 2002: CENTER_DRILL #50 and TOOL_DIMENSION #52, #53 are fdis2001 instances (#51 is in the 2002 form)
    assert [n.split(": ", 1)[1].split(" were")[0] for n in mixed.notes] == ["3 instance(s) of edition fdis2001"]


def test_a_2001_rule_no_instance_can_satisfy_is_checked_by_its_evident_intent() -> None:
    """2001 trimmed_curve WR3, 'parameter' IN TYPEOF(SELF.master_representation): TYPEOF of an
    enumeration value names its type, never an item, so the rule is FALSE for every curve (a
    schema defect); its evident intent, master_representation = .PARAMETER. (the edition's trims are
    parameter values, its Annex example trims so), is checked instead and the result says so.
    2002 has no such rule; 2001 definitional_representation WR1 names an entity no schema declares
    and has no intent to check: not checked, listed (ontology stats)."""
    curves = FIXTURES / "trimmed_curves_fdis2001.stp"
    [finding] = sg.validate([curves]).results
    assert (finding.p21_id, finding.severity, finding.shape) == (9, "Violation", SHAPES + "fdis2001.trimmed_curve-wr3")
    assert finding.message.startswith("trimmed_curve WR3 (schema defect, its intent checked: master_representation "
                                      "is .PARAMETER.)")
    assert sg.validate([curves], edition="2002").results == []
