"""The generated SHACL shapes: snapshot, meta-SHACL, rule coverage, exactness of the Core forms."""

from __future__ import annotations

from pathlib import Path

import pytest
from rdflib import RDF, SH, Graph, Literal
from rdflib.compare import graph_diff, isomorphic

from stepnc_graph.express import parse_file
from stepnc_graph.generators.shacl import SHAPES, ShapesGenerator
from stepnc_graph.schema import build_model
from stepnc_graph.schema.catalog import Catalog

ROOT = Path(__file__).resolve().parent.parent
OWL_FIX = Path(__file__).parent / "fixtures" / "owl"
FIX = Path(__file__).parent / "fixtures" / "validate"


def tiny_generator() -> ShapesGenerator:
    model = build_model(parse_file(OWL_FIX / "tiny.exp"))
    catalog = Catalog(OWL_FIX, ("tiny.exp",), {}, "https://w3id.org/stepnc-graph/iso14649#",
                      "https://w3id.org/stepnc-graph/iso14649/", "0.1.0")
    return ShapesGenerator(model, catalog)


def test_tiny_shapes_match_snapshot() -> None:
    """Snapshot: tests/fixtures/validate/tiny_shapes.ttl (regenerate deliberately when the mapping changes)."""
    got = Graph().parse(data=tiny_generator().outputs()["tiny.ttl"], format="turtle")
    want = Graph().parse(FIX / "tiny_shapes.ttl")
    if not isomorphic(got, want):
        _, only_got, only_want = graph_diff(got, want)
        pytest.fail(f"only generated:\n{only_got.serialize(format='nt')}\nonly snapshot:\n"
                    f"{only_want.serialize(format='nt')}")


def test_tiny_constructs() -> None:
    g = Graph().parse(data=tiny_generator().outputs()["tiny.ttl"], format="turtle")
    points = SHAPES["bolt.points"]
    assert (points, SH.minCount, Literal(1)) in g and (points, SH.maxCount, Literal(1)) in g
    assert (points, SH.node, SHAPES.ListMin2) in g  # LIST [2:?]: the second cell exists
    assert (SHAPES["nut.fits"], SH.minCount, Literal(1)) in g  # SET [1:?]
    assert (SHAPES["part-abstract"], SH.targetClass, None) in g
    assert (SHAPES["bolt-wr1"], RDF.type, SH.NodeShape) in g
    ok = SHAPES["bolt.ok"]
    assert (ok, SH.minCount, None) not in g  # OPTIONAL


def test_shipped_shapes_pass_shacl_shacl() -> None:
    """The shapes graph is itself valid SHACL (pySHACL's meta-SHACL check raises otherwise)."""
    import pyshacl

    shapes = Graph()
    for f in sorted((ROOT / "shapes").glob("*.ttl")):
        shapes.parse(f)
    conforms, _, text = pyshacl.validate(Graph(), shacl_graph=shapes, meta_shacl=True)
    assert conforms, text


@pytest.fixture(scope="module")
def coverage():  # type: ignore[no-untyped-def]
    from stepnc_graph.schema.catalog import load_catalog_model

    catalog, model = load_catalog_model()  # with the rules' expressions (the compiled model has none)
    return ShapesGenerator(model, catalog).coverage()


def test_the_generator_refuses_a_model_without_rule_expressions() -> None:
    from stepnc_graph.schema.catalog import iso14649

    catalog, model = iso14649()
    with pytest.raises(ValueError, match="load_catalog_model"):
        ShapesGenerator(model, catalog)


@pytest.mark.parametrize("schema,target", [
    ("turning_schema", 1.0), ("turning_machine_tool_schema", 1.0), ("machining_schema", 0.9),
    ("milling_schema", 0.9), ("milling_tool_schema", 0.9)])
def test_where_rule_coverage_targets(coverage, schema: str, target: float) -> None:  # type: ignore[no-untyped-def]
    rules = [r for r in coverage if r.schema == schema]
    done = sum(r.translated for r in rules)
    assert not rules or done / len(rules) >= target, [r for r in rules if not r.translated]


def test_untranslated_rules_say_why(coverage) -> None:  # type: ignore[no-untyped-def]
    missing = [r for r in coverage if not r.translated]
    assert missing and all(r.reason for r in missing)
    wr4 = next(r for r in missing if (r.owner, r.label) == ("countersunk_hole", "wr4"))
    assert "order" in (wr4.reason or "")


def test_core_form_for_exists_and_comparison() -> None:
    """facing_rough WR1 `EXISTS(allowance) AND (allowance >= 0.0)` is sh:minCount 1 + sh:minInclusive 0.0."""
    g = Graph().parse(ROOT / "shapes" / "turning_schema.ttl")
    prop = SHAPES["facing_rough-wr1.allowance"]
    assert (prop, SH.minCount, Literal(1)) in g
    assert g.value(prop, SH.minInclusive).toPython() == 0
    assert (SHAPES["facing_rough-wr1"], SH.targetClass, None) in g


def test_ontology_stats_lists_rules_and_reasons() -> None:
    import json

    from click.testing import CliRunner

    from stepnc_graph.cli import main

    res = CliRunner().invoke(main, ["ontology", "stats", "--format", "json"])
    doc = json.loads(res.output)
    turning = next(r for r in doc["where_rules"] if r["schema"] == "turning_schema")
    assert (turning["translated"], turning["total"]) == (4, 4)
    machining = next(r for r in doc["where_rules"] if r["schema"] == "machining_schema")
    assert [u["rule"] for u in machining["untranslated"]] == ["countersunk_hole.wr4"]
