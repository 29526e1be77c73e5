"""The OWL rendering: a snapshot compared as RDF graphs, then the shipped ontology vs the model."""

from __future__ import annotations


import pytest
from rdflib import OWL, RDF, RDFS, XSD, Graph, Literal, URIRef
from rdflib.collection import Collection
from rdflib.compare import graph_diff, isomorphic, to_isomorphic

from stepnc_graph.express import parse_file
from stepnc_graph.generators.owl import OwlGenerator, holds_list
from stepnc_graph.core.naming import P21, STEPNC
from stepnc_graph.schema import build_model
from stepnc_graph.schema.catalog import Catalog
from stepnc_graph.vocabulary.typemap import value_shape

from conftest import FIXTURES, ROOT

OWL_FIX = FIXTURES / "owl"


def tiny_graph() -> Graph:
    model = build_model(parse_file(OWL_FIX / "tiny.exp"))
    catalog = Catalog(OWL_FIX, ("tiny.exp",), {}, "https://w3id.org/stepnc-graph/iso14649#",
                      "https://w3id.org/stepnc-graph/iso14649/", "0.1.0")
    return OwlGenerator(model, catalog).schema_graph("tiny")


def test_tiny_schema_matches_snapshot() -> None:
    """Snapshot: tests/fixtures/owl/tiny.ttl (regenerate deliberately if conventions change)."""
    got = tiny_graph()
    want = Graph().parse(OWL_FIX / "tiny.ttl")
    if not isomorphic(got, want):
        _, only_got, only_want = graph_diff(to_isomorphic(got), to_isomorphic(want))
        pytest.fail("snapshot differs\n+ " + only_got.serialize(format="nt") + "\n- " + only_want.serialize(format="nt"))


@pytest.fixture(scope="module")
def tiny() -> Graph:
    return tiny_graph()


def test_entity_class_hierarchy_and_disjointness(tiny: Graph) -> None:
    assert (STEPNC.bolt, RDF.type, OWL.Class) in tiny
    assert (STEPNC.bolt, RDFS.subClassOf, STEPNC.part) in tiny
    assert (STEPNC.part, P21.abstract, Literal(True)) in tiny
    assert (STEPNC.bolt, RDFS.label, Literal("bolt")) in tiny
    node = next(tiny.subjects(RDF.type, OWL.AllDisjointClasses))
    assert set(Collection(tiny, tiny.value(node, OWL.members))) == {STEPNC.bolt, STEPNC.nut}


def test_attribute_properties(tiny: Graph) -> None:
    length = STEPNC["bolt.length"]
    assert (length, RDF.type, OWL.DatatypeProperty) in tiny
    assert (length, RDFS.range, XSD.double) in tiny  # defined type -> typed literal
    assert (length, P21.expressType, Literal("length_measure")) in tiny
    assert (length, P21.position, Literal(3)) in tiny  # after part.name, part.tags
    assert (STEPNC["part.name"], P21.position, Literal(1)) in tiny
    assert (STEPNC["bolt.points"], RDFS.range, P21.List) in tiny  # OWL 2 DL reserves rdf:List
    assert (STEPNC["bolt.points"], P21.aggregate, Literal("LIST [2:?]")) in tiny
    assert (STEPNC["nut.fits"], RDFS.range, STEPNC.bolt) in tiny  # SET -> repeated values
    assert (STEPNC["nut.fits"], RDF.type, OWL.ObjectProperty) in tiny
    assert (STEPNC["part.tags"], RDF.type, OWL.DatatypeProperty) in tiny
    assert (STEPNC["nut.holder"], OWL.inverseOf, STEPNC["bolt.value"]) in tiny
    assert (STEPNC["bolt.ok"], P21.optional, Literal(True)) in tiny


def test_logical_range_admits_unknown(tiny: Graph) -> None:
    rng = tiny.value(STEPNC["bolt.ok"], RDFS.range)
    assert set(Collection(tiny, tiny.value(rng, OWL.unionOf))) == {XSD.boolean, P21.logicalUnknown}


def test_enumeration_items_are_scoped(tiny: Graph) -> None:
    assert (STEPNC["side.left"], RDF.type, STEPNC.side) in tiny
    assert (STEPNC["hand.left"], RDF.type, STEPNC.hand) in tiny
    assert STEPNC["side.left"] != STEPNC["hand.left"]
    assert list(Collection(tiny, tiny.value(STEPNC.side, OWL.oneOf))) == [STEPNC["side.left"], STEPNC["side.right"]]


def test_select_members_are_subclasses_queryable(tiny: Graph) -> None:
    rows = tiny.query("SELECT ?c WHERE { ?c rdfs:subClassOf* stepnc:value_select }",
                      initNs={"rdfs": RDFS, "stepnc": STEPNC})
    assert {r[0] for r in rows} == {STEPNC.value_select, STEPNC.length_measure, STEPNC.part, STEPNC.bolt,
                                    STEPNC.nut}
    assert (STEPNC.length_measure, RDFS.subClassOf, P21.TypedValue) in tiny
    assert (STEPNC.length_measure, P21.underlyingDatatype, XSD.double) in tiny


# -- the shipped ontology ----------------------------------------------------


@pytest.fixture(scope="module")
def shipped() -> Graph:
    g = Graph()
    for ttl in sorted((ROOT / "ontology").glob("*.ttl")):
        g.parse(ttl)
    return g


SEED_SCHEMAS = ["turning_schema", "turning_machine_tool_schema", "turning_specific_feature_schema"]


@pytest.mark.parametrize("schema", SEED_SCHEMAS)
def test_every_seed_declaration_is_in_the_ontology(schema: str, shipped: Graph, iso_model) -> None:  # type: ignore[no-untyped-def]
    catalog, model = iso_model
    n = catalog.naming
    ontology = n.ontology(schema)
    assert (ontology, RDF.type, OWL.Ontology) in shipped
    for decl in model.in_schema(schema):
        iri = n.declaration(decl.name)
        assert (iri, RDFS.isDefinedBy, ontology) in shipped, decl.name
        for st in getattr(decl, "supertypes", ()):
            assert (iri, RDFS.subClassOf, n.declaration(st)) in shipped
    for e in (d for d in model.in_schema(schema) if d.name in model.entities):
        positions = {s.attribute.key: s.index + 1 for s in model.part21_attributes(e.name)}
        for a in model.entity(e.name).attributes:
            p = n.attribute(e.name, a.name)
            shape = value_shape(model, n, a.type)
            want_range = P21.List if holds_list(shape) else shape.leaf.range
            got_range = shipped.value(p, RDFS.range)
            if not shape.leaf.logical:
                assert got_range == want_range, (p, got_range, want_range)
            assert (p, RDFS.domain, n.declaration(e.name)) in shipped
            if a.kind == "explicit":
                assert shipped.value(p, P21.position) == Literal(positions[a.key]), p


def test_iso_clause_annotations(shipped: Graph) -> None:
    assert (STEPNC.outer_diameter, P21.isoClause, Literal("ISO/DIS 14649-12:2003, 5.2.2.1")) in shipped
    assert (STEPNC.cut_in, P21.isoClause, Literal("ISO/DIS 14649-12:2003, C.2")) in shipped


def test_python_vocabulary_rejects_typos() -> None:
    from stepnc_graph.vocabulary.terms import P21 as P21_TERMS
    from stepnc_graph.vocabulary.terms import STEPNC as TERMS

    assert TERMS.turning_workingstep == URIRef(str(STEPNC) + "turning_workingstep")
    assert TERMS["machining_operation.its_id"] == STEPNC["machining_operation.its_id"]
    assert P21_TERMS.position == P21.position
    with pytest.raises(AttributeError):
        TERMS.turning_workingstp  # noqa: B018


# -- OWL 2 DL, checked without Java (tests/test_owl_dl.py runs the OWL API and HermiT) ---------


BUILTIN_ANNOTATIONS = {RDFS.label, RDFS.comment, RDFS.seeAlso, RDFS.isDefinedBy, OWL.versionInfo,
                       OWL.deprecated}


def test_no_iri_is_two_kinds_of_property(shipped: Graph) -> None:
    """OWL 2 DL forbids punning between property kinds: a sub-property has its parent's kind."""
    kinds: dict[URIRef, set[URIRef]] = {}
    for kind in (OWL.DatatypeProperty, OWL.ObjectProperty, OWL.AnnotationProperty, RDF.Property):
        for p in shipped.subjects(RDF.type, kind):
            kinds.setdefault(p, set()).add(kind)  # type: ignore[arg-type]
    assert {p: k for p, k in kinds.items() if len(k) > 1} == {}
    assert not set(shipped.subjects(RDF.type, RDF.Property))
    mixed = [(s, o) for s, o in shipped.subject_objects(RDFS.subPropertyOf) if kinds.get(s) != kinds.get(o)]  # type: ignore[arg-type]
    assert mixed == []


def test_generic_property_of_mixed_values_is_an_annotation(shipped: Graph) -> None:
    """attr:diameter holds a length in milling_tool_dimension and a toleranced length in round_hole."""
    from stepnc_graph.core.naming import generic_attribute, generic_attribute_of_kind

    diameter = generic_attribute("diameter")
    assert (diameter, RDF.type, OWL.AnnotationProperty) in shipped
    literal, node = generic_attribute_of_kind("diameter", "literal"), generic_attribute_of_kind("diameter", "node")
    assert (STEPNC["milling_tool_dimension.diameter"], RDFS.subPropertyOf, literal) in shipped
    assert (STEPNC["round_hole.diameter"], RDFS.subPropertyOf, node) in shipped
    assert {diameter} == set(shipped.subjects(RDFS.seeAlso, literal)) == set(shipped.subjects(RDFS.seeAlso, node))
    assert (generic_attribute("its_id"), RDF.type, OWL.DatatypeProperty) in shipped  # one kind: as before


def test_no_reserved_vocabulary_as_range_and_no_one_operand_union(shipped: Graph) -> None:
    assert list(shipped.subjects(RDFS.range, RDF.List)) == []
    assert len(list(shipped.subjects(RDFS.range, P21.List))) > 40
    short = [s for s, lst in shipped.subject_objects(OWL.unionOf) if len(list(Collection(shipped, lst))) < 2]  # type: ignore[arg-type]
    assert short == []
    assert (STEPNC.reversible_topology, OWL.unionOf, None) in shipped


def test_annotation_properties_are_declared(shipped: Graph) -> None:
    declared = set(shipped.subjects(RDF.type, OWL.AnnotationProperty))
    properties = declared | set(shipped.subjects(RDF.type, OWL.DatatypeProperty)) | set(
        shipped.subjects(RDF.type, OWL.ObjectProperty))
    structural = {str(RDF), str(RDFS), str(OWL)}
    used = {p for p in shipped.predicates() if not any(str(p).startswith(ns) for ns in structural)}
    assert sorted(used - properties) == []
    assert BUILTIN_ANNOTATIONS.isdisjoint(declared)


def test_logical_unknown_is_a_defined_datatype(shipped: Graph) -> None:
    """HermiT accepts a datatype outside the OWL 2 map only with a definition."""
    definition = shipped.value(P21.logicalUnknown, OWL.equivalentClass)
    assert definition is not None
    assert list(Collection(shipped, shipped.value(definition, OWL.oneOf))) == [Literal("UNKNOWN", datatype=XSD.string)]


def _superclasses(g: Graph, c: URIRef) -> set[URIRef]:
    return set(g.transitive_objects(c, RDFS.subClassOf))  # type: ignore[arg-type]


def test_no_class_is_below_two_disjoint_classes(shipped: Graph) -> None:
    """No class is empty by disjointness: ISO 10303-42 lets vertex_point be a topological and a
    geometric representation item, which a ONEOF on representation_item forbade."""
    disjoint: set[frozenset[URIRef]] = set()
    for node in shipped.subjects(RDF.type, OWL.AllDisjointClasses):
        members = list(Collection(shipped, shipped.value(node, OWL.members)))
        disjoint |= {frozenset((a, b)) for a in members for b in members if a != b}  # type: ignore[misc]
    empty = {}
    for c in set(shipped.subjects(RDF.type, OWL.Class)):
        above = _superclasses(shipped, c)  # type: ignore[arg-type]
        clashes = [tuple(sorted(pair)) for pair in disjoint if pair <= above]
        if clashes:
            empty[c] = clashes
    assert empty == {}
    assert {STEPNC.topological_representation_item, STEPNC.geometric_representation_item} <= _superclasses(
        shipped, STEPNC.vertex_point)
