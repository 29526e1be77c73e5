"""EXPRESS schemas -> one OWL ontology (Turtle file) per schema.

Conventions are those of ``ontology/README.md``:
ENTITY -> owl:Class (SUBTYPE OF -> rdfs:subClassOf, ONEOF -> owl:AllDisjointClasses,
ABSTRACT -> p21:abstract annotation, to be checked by SHACL, not OWL);
explicit/derived/inverse attribute -> one property per declaring entity;
defined type -> owl:Class of typed values (used where the type name must be
kept, i.e. inside a SELECT) with the XSD datatype as annotation;
ENUMERATION -> owl:Class with one individual per item (owl:oneOf);
SELECT -> owl:Class, each member rdfs:subClassOf it, and owl:unionOf.

The output is OWL 2 DL (checked by ``tests/test_owl_dl.py`` with the OWL API's
profile checker and HermiT): no IRI is both a data and an object property,
annotation properties from other vocabularies are declared, list-valued
properties range over ``p21:List`` (OWL 2 DL reserves ``rdf:List``) and a
one-member SELECT is an equivalent class, not a one-operand union.
"""

from __future__ import annotations

from rdflib import OWL, RDF, RDFS, XSD, BNode, Graph, Literal, URIRef
from rdflib.term import Node
from rdflib.collection import Collection
from rdflib.namespace import DCTERMS, SKOS

from stepnc_graph.core.naming import P21, P21_ONTOLOGY, Naming
from stepnc_graph.schema.catalog import Catalog
from stepnc_graph.schema.model import (
    Attribute,
    DefinedType,
    Entity,
    EnumerationType,
    SchemaInfo,
    SelectType,
    SupertypeExpr,
    WhereRule,
)
from stepnc_graph.schema.view import SchemaModel
from stepnc_graph.generators.rdfio import stable_turtle
from stepnc_graph.vocabulary.typemap import ValueShape, value_shape

KIND_NAMES = {Entity: "ENTITY", DefinedType: "DEFINED_TYPE", EnumerationType: "ENUMERATION",
              SelectType: "SELECT"}

#: Annotation properties of other vocabularies the generated ontologies use; OWL 2 DL wants each
#: declared in the ontology that uses it or in one it imports. The schema ontologies' two are
#: declared once, in p21.ttl (which each imports), so that no triple is in two files.
FOREIGN_ANNOTATIONS = (DCTERMS.title, DCTERMS.source, SKOS.definition)
SCHEMA_ANNOTATIONS = (DCTERMS.title, DCTERMS.source)


def holds_list(shape: ValueShape) -> bool:
    """Whether an attribute of this shape has RDF collections as values (itself a LIST/ARRAY/BAG,
    or a SET of them, one triple per member)."""
    return shape.form == "list" or (shape.form == "repeated" and shape.element is not None
                                    and shape.element.form == "list")


def is_data(shape: ValueShape) -> bool:
    """Whether an attribute of this shape is an ``owl:DatatypeProperty`` (literal values)."""
    return not holds_list(shape) and shape.leaf.form == "literal"


def declare_annotations(g: Graph) -> None:
    """Declare every annotation property of :data:`FOREIGN_ANNOTATIONS` that ``g`` uses."""
    for p in FOREIGN_ANNOTATIONS:
        if next(g.triples((None, p, None)), None) is not None:
            g.add((p, RDF.type, OWL.AnnotationProperty))


def _where(rule: WhereRule) -> Literal:
    return Literal(f"{rule.label}: {rule.source}")


class OwlGenerator:
    """Builds ``<schema>.ttl`` for every schema of the model."""

    def __init__(self, model: SchemaModel, catalog: Catalog, naming: Naming | None = None) -> None:
        self.model = model
        self.catalog = catalog
        self.n = naming or catalog.naming

    # -- public -----------------------------------------------------------

    def outputs(self) -> dict[str, str]:
        return {f"{name}.ttl": stable_turtle(self.schema_graph(name)) for name in sorted(self.model.schemas)}

    def schema_graph(self, schema: str) -> Graph:
        g = self.new_graph()
        info = self.model.schemas[schema]
        self.add_ontology(g, info)
        for decl in self.model.in_schema(schema):
            self.add_declaration(g, decl, info)
        return g  # dcterms:title and dcterms:source are declared in p21.ttl, which every schema imports

    def new_graph(self) -> Graph:
        g = Graph()
        g.bind("stepnc", self.n.namespace)
        g.bind("p21", str(P21))
        g.bind("owl", OWL)
        g.bind("dcterms", DCTERMS)
        return g

    # -- pieces -----------------------------------------------------------

    def add_ontology(self, g: Graph, info: SchemaInfo) -> None:
        o = self.n.ontology(info.name)
        g.add((o, RDF.type, OWL.Ontology))
        g.add((o, RDFS.label, Literal(info.name)))
        if info.title:
            g.add((o, DCTERMS.title, Literal(f"{info.iso_part} {info.title}" if info.iso_part else info.title)))
        g.add((o, OWL.versionInfo, Literal(info.version or self.catalog.ontology_version)))
        g.add((o, OWL.versionIRI, self.n.ontology_version(info.name, self.catalog.ontology_version)))
        if info.source:
            g.add((o, DCTERMS.source, Literal(info.source)))
        if info.edition:
            g.add((o, RDFS.comment, Literal(
                f"OWL rendering of the EXPRESS schema {info.name} ({info.edition}; status: {info.status}), "
                f"generated by stepnc-graph from ontology/express/{info.file.split('/')[-1]}.")))
        if info.iso_part:
            g.add((o, P21.isoPart, Literal(info.iso_part)))
        g.add((o, OWL.imports, URIRef(P21_ONTOLOGY)))
        for target in sorted({i.schema for i in info.interfaces}):
            g.add((o, OWL.imports, self.n.ontology(target)))

    def annotate(self, g: Graph, iri: URIRef, decl: Entity | DefinedType | EnumerationType | SelectType,
                 info: SchemaInfo) -> None:
        g.add((iri, RDFS.label, Literal(decl.name)))
        g.add((iri, P21.expressName, Literal(decl.name)))
        g.add((iri, P21.expressKind, Literal(KIND_NAMES[type(decl)])))
        g.add((iri, P21.schema, Literal(info.name)))
        g.add((iri, RDFS.isDefinedBy, self.n.ontology(info.name)))
        if info.iso_part:
            g.add((iri, P21.isoPart, Literal(info.iso_part)))
        clause = info.clauses.get(decl.name)
        if clause:
            g.add((iri, P21.isoClause, Literal(f"{info.edition}, {clause}")))
        for rule in decl.where_rules:
            g.add((iri, P21.whereRule, _where(rule)))

    def where_from(self, decl_name: str) -> str:
        info = self.model.schemas[self.model[decl_name].schema]
        clause = info.clauses.get(decl_name)
        return f"{info.iso_part} {clause}" if clause else f"{info.iso_part} ({info.name})"

    def add_declaration(self, g: Graph, decl: Entity | DefinedType | EnumerationType | SelectType,
                        info: SchemaInfo) -> None:
        iri = self.n.declaration(decl.name)
        g.add((iri, RDF.type, OWL.Class))
        self.annotate(g, iri, decl, info)
        if isinstance(decl, Entity):
            self.add_entity(g, iri, decl)
        elif isinstance(decl, DefinedType):
            self.add_defined(g, iri, decl)
        elif isinstance(decl, EnumerationType):
            self.add_enumeration(g, iri, decl)
        else:
            self.add_select(g, iri, decl)

    def add_entity(self, g: Graph, iri: URIRef, e: Entity) -> None:
        for st in e.supertypes:
            g.add((iri, RDFS.subClassOf, self.n.declaration(st)))
        g.add((iri, P21.abstract, Literal(e.abstract)))
        if e.supertype_expr is not None:
            g.add((iri, P21.supertypeExpression, Literal(str(e.supertype_expr))))
            self.add_disjointness(g, e.supertype_expr)
        for u in e.unique_rules:
            g.add((iri, P21.uniqueRule, Literal(f"{u.label}: {', '.join(u.attributes)}")))
        for r in e.redeclarations:
            kind = "DERIVE " if r.derived else ""
            g.add((iri, P21.redeclaration, Literal(f"{kind}SELF\\{r.supertype}.{r.name} : {r.type}")))
        explicit = len(e.explicit)
        supers = ", ".join(e.supertypes) or "none"
        g.add((iri, RDFS.comment, Literal(
            f"Entity {e.name} of {self.model.schemas[e.schema].iso_part} ({e.schema})"
            f"{', abstract' if e.abstract else ''}; supertypes: {supers}; "
            f"{explicit} explicit attribute(s) of its own; {len(self.model.part21_attributes(e.name))} "
            f"Part 21 parameter(s) in all.")))
        positions = {s.attribute.key: s.index + 1 for s in self.model.part21_attributes(e.name)}
        for a in e.attributes:
            self.add_attribute(g, a, positions.get(a.key))

    def add_disjointness(self, g: Graph, expr: SupertypeExpr) -> None:
        """ONEOF(a, b, ...) -> owl:AllDisjointClasses over the named operands."""
        if expr.op == "ONEOF":
            names = sorted(o for o in expr.operands if isinstance(o, str))
            if len(names) >= 2:
                node = BNode(f"disjoint_{'_'.join(names)}")
                g.add((node, RDF.type, OWL.AllDisjointClasses))
                members = BNode(f"members_{'_'.join(names)}")
                Collection(g, members, [self.n.declaration(x) for x in names])
                g.add((node, OWL.members, members))
        for o in expr.operands:
            if isinstance(o, SupertypeExpr):
                self.add_disjointness(g, o)

    def add_attribute(self, g: Graph, a: Attribute, position: int | None) -> None:
        p = self.n.attribute(a.entity, a.name)
        shape = value_shape(self.model, self.n, a.type)
        g.add((p, RDF.type, OWL.DatatypeProperty if is_data(shape) else OWL.ObjectProperty))
        g.add((p, RDFS.label, Literal(a.name)))
        g.add((p, P21.expressName, Literal(a.name)))
        g.add((p, P21.declaredBy, self.n.declaration(a.entity)))
        g.add((p, P21.attributeKind, Literal(a.kind)))
        g.add((p, P21.expressType, Literal(str(a.type))))
        g.add((p, RDFS.domain, self.n.declaration(a.entity)))
        g.add((p, RDFS.isDefinedBy, self.n.ontology(self.model.entity(a.entity).schema)))
        self.add_range(g, p, shape)
        if a.kind == "explicit":
            g.add((p, P21.optional, Literal(a.optional)))
            if position is not None:
                g.add((p, P21.position, Literal(position)))
        if a.expression:
            g.add((p, P21.derivation, Literal(a.expression)))
        if a.inverse_of:
            forward = self.model.attribute(*a.inverse_of)
            if forward is not None:
                fwd_iri = self.n.attribute(forward.entity, forward.name)
                g.add((p, P21.inverseFor, fwd_iri))
                if value_shape(self.model, self.n, forward.type).form in ("node", "repeated"):
                    g.add((p, OWL.inverseOf, fwd_iri))
        what = {"explicit": "Attribute", "derived": "Derived attribute", "inverse": "Inverse attribute"}[a.kind]
        g.add((p, RDFS.comment, Literal(
            f"{what} {a.name} of {a.entity}, type {a.type}"
            f"{' (optional)' if a.optional else ''}"
            f"{f'; Part 21 parameter {position} of {a.entity}' if position else ''}.")))

    def add_range(self, g: Graph, p: URIRef, shape: ValueShape) -> None:
        if shape.aggregate:
            g.add((p, P21.aggregate, Literal(shape.aggregate)))
            g.add((p, P21.elementType, self.range_term(g, shape.leaf)))
        g.add((p, RDFS.range, P21.List if holds_list(shape) else self.range_term(g, shape.leaf)))

    def range_term(self, g: Graph, shape: ValueShape) -> URIRef | BNode:
        if not shape.logical:
            return shape.range
        # A fresh node per use: blank nodes used once are written inline, so
        # their random labels never reach the output (byte-stable Turtle).
        node = BNode()
        g.add((node, RDF.type, RDFS.Datatype))
        members = BNode()
        Collection(g, members, [XSD.boolean, P21.logicalUnknown])
        g.add((node, OWL.unionOf, members))
        return node

    def add_defined(self, g: Graph, iri: URIRef, t: DefinedType) -> None:
        chain, base = self.model.underlying_chain(t.name)
        g.add((iri, RDFS.subClassOf, P21.TypedValue))
        g.add((iri, P21.underlyingType, Literal(str(t.underlying))))
        shape = value_shape(self.model, self.n, t.underlying)
        if shape.form == "literal":
            g.add((iri, P21.underlyingDatatype, self.range_term(g, shape)))
        g.add((iri, RDFS.comment, Literal(
            f"Defined type {t.name} = {t.underlying} ({self.where_from(t.name)}). Attribute values of this "
            f"type are plain literals; this class types the value nodes that keep the type name, as "
            f"Part 21 does inside a SELECT.")))

    def add_enumeration(self, g: Graph, iri: URIRef, t: EnumerationType) -> None:
        items: list[Node] = [self.n.enum_item(t.name, item) for item in t.items]
        for item, name in zip(items, t.items, strict=True):
            g.add((item, RDF.type, OWL.NamedIndividual))
            g.add((item, RDF.type, iri))
            g.add((item, RDFS.label, Literal(name)))
            g.add((item, P21.expressName, Literal(name)))
            g.add((item, RDFS.isDefinedBy, self.n.ontology(t.schema)))
        one_of = BNode(f"oneof_{t.name}")
        Collection(g, one_of, items)
        g.add((iri, OWL.oneOf, one_of))
        g.add((iri, RDFS.comment, Literal(
            f"Enumeration {t.name} ({self.where_from(t.name)}): {', '.join(t.items)}. Each item is an "
            f"individual scoped by this type.")))

    def add_select(self, g: Graph, iri: URIRef, t: SelectType) -> None:
        members: list[Node] = [self.n.declaration(m) for m in t.members]
        for m in members:  # said here, where the members are interfaced (imported), not in their ontology
            g.add((m, RDFS.subClassOf, iri))
        if len(members) == 1:  # OWL 2 DL wants two operands or more in a union
            g.add((iri, OWL.equivalentClass, members[0]))
        else:
            union = BNode(f"union_{t.name}")
            Collection(g, union, members)
            g.add((iri, OWL.unionOf, union))
        g.add((iri, RDFS.comment, Literal(
            f"Select type {t.name} ({self.where_from(t.name)}): one of {', '.join(t.members)}. Members are "
            f"subclasses, so rdfs:subClassOf* finds every admissible class.")))
