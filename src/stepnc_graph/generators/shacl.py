"""EXPRESS schemas -> SHACL shapes (``shapes/<schema>.ttl``), one node shape per entity.

What each EXPRESS construct becomes (the values are those of ``ontology/README.md``):

* explicit attribute -> a property shape: not OPTIONAL -> ``sh:minCount 1``;
  single value -> ``sh:maxCount 1``; entity -> ``sh:class``; simple and
  defined types -> ``sh:datatype`` plus the value ranges of the defined types'
  WHERE rules; enumeration -> ``sh:in`` of its items; SELECT -> ``sh:class``
  of the select (every member, nested selects and typed-value classes are
  subclasses of it in ``shapes/support.ttl``);
* SET bounds -> counts of the repeated triples; LIST/ARRAY/BAG bounds ->
  ``sh:node`` of a shared list shape (``shapes:ListMin2``: the second cell
  exists) and member constraints on ``(attr [sh:zeroOrMorePath rdf:rest] rdf:first)``;
  UNIQUE members and the empty-or-marked cases -> SHACL-SPARQL;
* ABSTRACT -> the instance must also belong to a subtype (``sh:or`` of them);
  ONEOF -> no instance of two of the operands (``sh:not``);
* entity WHERE rules -> a node shape each (:mod:`.express_sparql`: SHACL Core
  when the meaning is the same, else SHACL-SPARQL); untranslatable rules are
  listed by :meth:`ShapesGenerator.coverage` with the reason.

**The class hierarchy.** The data holds each instance's most specific class
only; SHACL's ``sh:targetClass`` and ``sh:class`` follow ``rdfs:subClassOf``
*in the data graph*. ``shapes/support.ttl`` is that hierarchy (supertypes, SELECT
membership, enumeration items' types) and is part of every data graph the
shapes are run on: merged into the data for pySHACL, compiled into the queries
by :mod:`stepnc_graph.validation`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from decimal import Decimal
from typing import Any

from rdflib import RDF, RDFS, SH, XSD, BNode, Graph, Literal, Namespace, URIRef
from rdflib.collection import Collection
from rdflib.term import Node

from stepnc_graph.generators.express_sparql import (
    Translation,
    Untranslatable,
    defined_type_facets,
    express_text,
    translate_rule,
)
from stepnc_graph.generators.rdfio import stable_turtle
from stepnc_graph.generators.shacl_supertypes import add_abstract, add_oneof
from stepnc_graph.core.naming import P21, P21_NS, Naming
from stepnc_graph.schema.catalog import Catalog
from stepnc_graph.schema.model import (
    AggregateType,
    Attribute,
    BaseType,
    DefinedType,
    Entity,
    EnumerationType,
    NamedType,
    SimpleType,
    TypeRef,
    WhereRule,
)
from stepnc_graph.schema.view import SchemaModel
from stepnc_graph.vocabulary.typemap import XSD_OF, value_shape

SHAPES_NS = "https://w3id.org/stepnc-graph/shapes#"
SHAPES = Namespace(SHAPES_NS)


@dataclass(frozen=True)
class RuleCoverage:
    """One EXPRESS WHERE rule and what became of it."""

    schema: str
    owner: str  # entity or defined type
    label: str
    text: str
    translated: bool
    how: str  # "core", "sparql", "range" (defined type value range), "intent" (a schema defect's
    # evident intent, see express_sparql.never_satisfied) or "" when not translated
    reason: str | None = None


class ShapesGenerator:
    """Builds ``shapes/core.ttl``, ``shapes/support.ttl`` and ``shapes/<schema>.ttl``."""

    #: the namespace of the shapes it names (also for :mod:`.shacl_supertypes`)
    shapes = SHAPES

    def __init__(self, model: SchemaModel, catalog: Catalog, naming: Naming | None = None,
                 edition_classes: list[tuple[str, str]] | None = None, shape_prefix: str = "") -> None:
        self.model = model
        self.catalog = catalog
        self.n = naming or catalog.naming
        #: (class of another edition, its 2002 counterpart) IRIs: subclass pairs the support graph adds
        self.edition_classes = edition_classes or []
        #: before each rule shape's name: another edition's rules are shapes of their own
        self.shape_prefix = shape_prefix
        self._coverage: list[RuleCoverage] = []
        self._translations: dict[tuple[str, str], Translation | Untranslatable] = {}
        self._facets: dict[str, list[tuple[str, Decimal | int]]] = {}
        self._derived: dict[tuple[str, str], list[str]] = {}  # attribute key -> entities deriving it
        for e in model.entities.values():
            for r in e.redeclarations:
                if r.derived:
                    target = model.attribute(r.supertype, r.name)
                    if target is not None:
                        self._derived.setdefault(target.key, []).append(e.name)
        self._translate_all()

    # -- rules --------------------------------------------------------------------------

    def _translate_all(self) -> None:
        for name, decl in sorted(self.model.declarations.items()):
            for rule in decl.where_rules:
                if rule.expr is None:
                    raise ValueError(f"{name} {rule.label}: the shapes generator needs the rules' parsed expressions; "
                                     "give it the model built from the EXPRESS (schema.catalog.load_catalog_model), "
                                     "not the compiled model commands read")
                text = express_text(rule.expr)
                try:
                    if isinstance(decl, Entity):
                        t = translate_rule(self.model, self.n, decl, rule.expr)
                        self._translations[(name, rule.label)] = t
                        how = "core" if t.core else "intent" if t.defect else "sparql"
                    elif isinstance(decl, DefinedType):
                        self._facets.setdefault(name, []).extend(defined_type_facets(rule.expr))
                        how = "range"
                    else:
                        raise Untranslatable(f"a WHERE rule on a {type(decl).__name__}")
                    self._coverage.append(RuleCoverage(decl.schema, name, rule.label, text, True, how))
                    if how == "intent":
                        self._coverage[-1] = dataclasses.replace(
                            self._coverage[-1], reason=f"schema defect: {t.defect}; its evident intent checked: {t.intent}")
                except Untranslatable as exc:
                    self._translations[(name, rule.label)] = exc
                    self._coverage.append(RuleCoverage(decl.schema, name, rule.label, text, False, "", str(exc)))

    def coverage(self) -> list[RuleCoverage]:
        """Every WHERE rule of the model: translated (how) or not (why)."""
        return list(self._coverage)

    # -- output ---------------------------------------------------------------------------

    def outputs(self) -> dict[str, str]:
        out = {"core.ttl": stable_turtle(self.core_graph()), "support.ttl": stable_turtle(self.support_graph())}
        for schema in sorted(self.model.schemas):
            g = self.schema_graph(schema)
            if len(g) > 0:
                out[f"{schema}.ttl"] = stable_turtle(g)
        return out

    def new_graph(self) -> Graph:
        g = Graph()
        g.bind("sh", SH)
        g.bind("shapes", SHAPES)
        g.bind("stepnc", self.n.namespace)
        g.bind("p21", P21_NS)
        return g

    def core_graph(self) -> Graph:
        """The prefixes SPARQL shapes use, and the shared list-bound shapes."""
        g = self.new_graph()
        ont = URIRef(SHAPES_NS[:-1])
        g.add((ont, RDF.type, URIRef("http://www.w3.org/2002/07/owl#Ontology")))
        g.add((ont, RDFS.label, Literal("stepnc-graph SHACL shapes")))
        g.add((ont, RDFS.comment, Literal(
            "Generated by stepnc-graph from the EXPRESS schemas in ontology/express/. shapes/support.ttl is the "
            "class hierarchy the shapes assume in the data graph.")))
        for prefix, ns in (("stepnc", self.n.namespace), ("p21", P21_NS),
                           ("rdf", str(RDF)), ("xsd", str(XSD))):
            decl = BNode(f"prefix_{prefix}")
            g.add((ont, SH.declare, decl))
            g.add((decl, SH.prefix, Literal(prefix)))
            g.add((decl, SH.namespace, Literal(ns, datatype=XSD.anyURI)))
        for n in sorted(self._list_bounds_used()):
            self._list_bound_shape(g, n)
        return g

    def _list_bounds_used(self) -> set[str]:
        names: set[str] = set()
        for e in self.model.entities.values():
            for a in e.explicit:
                t = self.model.base_type(a.type)
                while isinstance(t, AggregateType):
                    if t.lower:
                        names.add(f"ListMin{t.lower}")
                    if t.upper is not None:
                        names.add(f"ListMax{t.upper}")
                    t = self.model.base_type(t.element)
        return names

    def _list_bound_shape(self, g: Graph, name: str) -> URIRef:
        """``ListMinN``: the N-th cell exists; ``ListMaxN``: there is no (N+1)-th cell."""
        shape = SHAPES[name]
        n = int(name[7:])
        g.add((shape, RDF.type, SH.NodeShape))
        prop = BNode(f"{name}_path")
        g.add((shape, SH.property, prop))
        rests = n - 1 if name.startswith("ListMin") else n
        steps: list[Node] = [*([RDF.rest] * rests), RDF.first]
        path = self._sequence(g, steps)
        g.add((prop, SH.path, path))
        if name.startswith("ListMin"):
            g.add((prop, SH.minCount, Literal(1)))
            g.add((shape, RDFS.comment, Literal(f"A list of at least {n} members.")))
        else:
            g.add((prop, SH.maxCount, Literal(0)))
            g.add((shape, RDFS.comment, Literal(f"A list of at most {n} members.")))
        return shape

    @staticmethod
    def _sequence(g: Graph, steps: list[Node]) -> Node:
        if len(steps) == 1:
            return steps[0]
        head = BNode()
        Collection(g, head, steps)
        return head

    def support_graph(self) -> Graph:
        """rdfs:subClassOf for supertypes and SELECT membership; the enumeration items' types; the
        classes of other editions under their 2002 counterparts (:attr:`edition_classes`)."""
        g = Graph()
        g.bind("stepnc", self.n.namespace)
        for sub, sup in self.edition_classes:
            g.add((URIRef(sub), RDFS.subClassOf, URIRef(sup)))
        for e in self.model.entities.values():
            for st in e.supertypes:
                g.add((self.n.declaration(e.name), RDFS.subClassOf, self.n.declaration(st)))
        for t in self.model.types.values():
            if isinstance(t, EnumerationType):
                for item in t.items:
                    g.add((self.n.enum_item(t.name, item), RDF.type, self.n.declaration(t.name)))
            members = getattr(t, "members", None)
            if members is not None:
                for m in members:
                    g.add((self.n.declaration(m), RDFS.subClassOf, self.n.declaration(t.name)))
            if isinstance(t, DefinedType) and self.model.select_behind(t.name) is not None:
                g.add((self.n.declaration(t.name), RDFS.subClassOf, self.n.declaration(self.model.select_behind(t.name).name)))  # type: ignore[union-attr]
        return g

    # -- per schema ---------------------------------------------------------------------

    def schema_graph(self, schema: str) -> Graph:
        g = self.new_graph()
        for decl in self.model.in_schema(schema):
            if isinstance(decl, Entity):
                self.add_entity(g, decl)
            elif isinstance(decl, DefinedType) and self._typed_value_class(decl):
                self.add_typed_value(g, decl)
        return g

    def _typed_value_class(self, t: DefinedType) -> bool:
        """Whether values of ``t`` can be typed-value nodes: ``t`` is a member of some SELECT."""
        return any(t.name in self.model.select_closure(s.name) for s in self.model.types.values()
                   if getattr(s, "members", None) is not None)

    def annotate(self, g: Graph, shape: URIRef, decl_name: str, label: str) -> None:
        decl = self.model[decl_name]
        info = self.model.schemas[decl.schema]
        g.add((shape, RDFS.label, Literal(label)))
        g.add((shape, P21.schema, Literal(decl.schema)))
        clause = info.clauses.get(decl.name)
        source = info.edition or info.iso_part or decl.schema
        g.add((shape, P21.isoClause, Literal(f"{source}, {clause}" if clause else source)))

    def add_entity(self, g: Graph, e: Entity) -> None:
        cls = self.n.declaration(e.name)
        shape = SHAPES[e.name]
        g.add((shape, RDF.type, SH.NodeShape))
        g.add((shape, SH.targetClass, cls))
        self.annotate(g, shape, e.name, e.name)
        for a in e.explicit:
            self.add_attribute(g, shape, e, a)
        for r in e.redeclarations:
            target = self.model.attribute(r.supertype, r.name)
            if r.derived and target is not None:
                self.add_derived(g, shape, e, target)
        if e.abstract:
            add_abstract(self, g, e)
        if e.supertype_expr is not None:
            add_oneof(self, g, e, e.supertype_expr)
        for rule in e.where_rules:
            self.add_rule(g, e, rule)

    # -- attributes ---------------------------------------------------------------------

    def add_attribute(self, g: Graph, node_shape: URIRef, e: Entity, a: Attribute) -> None:
        prop = self.n.attribute(e.name, a.name)
        shape = SHAPES[f"{e.name}.{a.name}"]
        g.add((node_shape, SH.property, shape))
        g.add((shape, RDF.type, SH.PropertyShape))
        g.add((shape, SH.path, prop))
        self.annotate(g, shape, e.name, f"{e.name}.{a.name}")
        g.add((shape, P21.expressType, Literal(f"{'OPTIONAL ' if a.optional else ''}{a.type}")))
        form = value_shape(self.model, self.n, a.type).form
        base = self.model.base_type(a.type)
        if form == "repeated":
            assert isinstance(base, AggregateType)
            self.add_set(g, shape, e, a, base)
        else:
            if not a.optional:
                if a.key in self._derived:
                    self.add_required_or_derived(g, shape, prop, self._derived[a.key])
                else:
                    g.add((shape, SH.minCount, Literal(1)))
            g.add((shape, SH.maxCount, Literal(1)))
            self.add_value(g, shape, a.type, f"{e.name}.{a.name}", prop)

    def add_set(self, g: Graph, shape: URIRef, e: Entity, a: Attribute, t: AggregateType) -> None:
        """A top-level SET: one triple per member; ``()`` is ``p21:emptyAggregate``."""
        if not a.optional:
            if t.lower:
                g.add((shape, SH.minCount, Literal(t.lower)))
            else:
                self.add_sparql(g, shape, (
                    "SELECT $this WHERE { FILTER NOT EXISTS { $this $PATH ?value } "
                    f"FILTER NOT EXISTS {{ $this p21:emptyAggregate <{self.n.attribute(e.name, a.name)}> }} }}"),
                    "required: a SET, written () when empty")
        elif t.lower:
            raise NotImplementedError("an OPTIONAL SET with a lower bound")  # none in the shipped schemas
        if t.upper is not None:
            g.add((shape, SH.maxCount, Literal(t.upper)))
        self.add_value(g, shape, t.element, f"{e.name}.{a.name}", None)

    def add_required_or_derived(self, g: Graph, shape: URIRef, prop: URIRef, deriving: list[str]) -> None:
        """Mandatory, but subtypes that derive the value write ``*`` (``p21:derivedValue``) instead."""
        self.add_sparql(g, shape, (
            "SELECT $this WHERE { FILTER NOT EXISTS { $this $PATH ?value } "
            f"FILTER NOT EXISTS {{ $this p21:derivedValue <{prop}> }} }}"),
            f"required (written * by {', '.join(sorted(deriving))}, which derive it)")

    def add_derived(self, g: Graph, node_shape: URIRef, e: Entity, target: Attribute) -> None:
        shape = SHAPES[f"{e.name}.{target.name}-derived"]
        g.add((node_shape, SH.property, shape))
        g.add((shape, RDF.type, SH.PropertyShape))
        g.add((shape, SH.path, self.n.attribute(target.entity, target.name)))
        g.add((shape, SH.maxCount, Literal(0)))
        self.annotate(g, shape, e.name, f"{e.name}.{target.name}")
        g.add((shape, SH.message, Literal(f"{e.name} derives {target.name}: Part 21 writes *, not a value")))

    def add_sparql(self, g: Graph, shape: URIRef, select: str, message: str) -> None:
        c = BNode()
        g.add((shape, SH.sparql, c))
        g.add((c, RDF.type, SH.SPARQLConstraint))
        g.add((c, SH.select, Literal(select)))
        g.add((c, SH.prefixes, URIRef(SHAPES_NS[:-1])))
        g.add((c, SH.message, Literal(message)))

    # -- values ---------------------------------------------------------------------------

    def add_value(self, g: Graph, shape: Node, t: TypeRef, name: str, prop: URIRef | None) -> None:
        """Constraints every value node of ``shape`` must meet to be a value of type ``t``."""
        chain, base = self.model.underlying_chain(t.name) if isinstance(t, NamedType) else ([], t)
        for dt in chain:
            for facet, value in self._facets.get(dt, []):
                g.add((shape, SH[facet], Literal(value, datatype=XSD.integer if isinstance(value, int) else XSD.decimal)))
        if isinstance(base, SimpleType):
            if base.base is BaseType.LOGICAL:
                alternatives = []
                for dt in (XSD.boolean, P21.logicalUnknown):
                    alt = BNode()
                    g.add((alt, SH.datatype, dt))
                    alternatives.append(alt)
                self._list(g, shape, SH["or"], alternatives)
            else:
                g.add((shape, SH.datatype, XSD_OF[base.base]))
        elif isinstance(base, AggregateType):
            self.add_list(g, shape, base, name)
        elif isinstance(base, NamedType):
            decl = self.model[base.name]
            if isinstance(decl, EnumerationType):
                self._list(g, shape, SH["in"], [self.n.enum_item(decl.name, i) for i in decl.items])
            else:
                g.add((shape, SH["class"], self.n.declaration(base.name)))

    def add_list(self, g: Graph, shape: Node, t: AggregateType, name: str) -> None:
        """LIST/ARRAY/BAG: an rdf:List with bounded length, typed members, UNIQUE members."""
        if t.bound_text is not None:
            raise NotImplementedError("aggregate bounds given by expressions")  # none in the shipped schemas
        if t.lower:
            g.add((shape, SH.node, SHAPES[f"ListMin{t.lower}"]))
        if t.upper is not None:
            g.add((shape, SH.node, SHAPES[f"ListMax{t.upper}"]))
        members = SHAPES[f"{name}-members"]
        node = SHAPES[f"{name}-list"]
        g.add((shape, SH.node, node))
        g.add((node, RDF.type, SH.NodeShape))
        g.add((node, SH.property, members))
        g.add((members, RDF.type, SH.PropertyShape))
        rest = BNode()
        g.add((rest, SH.zeroOrMorePath, RDF.rest))
        g.add((members, SH.path, self._sequence(g, [rest, RDF.first])))
        if t.optional_elements:
            raise NotImplementedError("aggregates with OPTIONAL members")  # none in the shipped schemas
        if t.unique:
            self.add_sparql(g, node, (
                "SELECT DISTINCT $this WHERE { $this rdf:rest* ?a . $this rdf:rest* ?b . "
                "?a rdf:first ?value . ?b rdf:first ?value . FILTER(!sameTerm(?a, ?b)) }"),
                "members must be UNIQUE")
        self.add_value(g, members, t.element, f"{name}-member", None)

    def _list(self, g: Graph, subject: Node, pred: URIRef, items: list[Any]) -> None:
        head = BNode()
        Collection(g, head, items)
        g.add((subject, pred, head))

    # -- abstract, ONEOF ----------------------------------------------------------------------

    # -- WHERE rules ----------------------------------------------------------------------

    def add_rule(self, g: Graph, e: Entity, rule: WhereRule) -> URIRef | None:
        """The rule's shape, added to ``g``; None when the rule is not translated."""
        t = self._translations[(e.name, rule.label)]
        if isinstance(t, Untranslatable):
            return None
        shape = SHAPES[f"{self.shape_prefix}{e.name}-{rule.label}"]
        g.add((shape, RDF.type, SH.NodeShape))
        g.add((shape, SH.targetClass, self.n.declaration(e.name)))
        text = express_text(rule.expr)

        def describe(s: URIRef, message: bool = True) -> None:
            self.annotate(g, s, e.name, f"{e.name} {rule.label.upper()}")
            g.add((s, SHAPES.rule, Literal(rule.label.upper())))
            g.add((s, SHAPES.expressText, Literal(text)))
            if message and t.defect is None:
                g.add((s, SH.message, Literal(f"{e.name} {rule.label.upper()}: {text}")))
            elif message:
                g.add((s, SH.message, Literal(f"{e.name} {rule.label.upper()} (schema defect, its intent checked: "
                                              f"{t.intent}): {text}")))

        describe(shape)
        if t.defect is not None:
            g.add((shape, SHAPES.schemaDefect, Literal(t.defect)))
            g.add((shape, SHAPES.intentChecked, Literal(t.intent or "")))
        if t.note:
            g.add((shape, RDFS.comment, Literal(f"Exact reading: {t.note}.")))
        if t.core is not None:
            prop = SHAPES[f"{self.shape_prefix}{e.name}-{rule.label}.{t.core.attribute.name}"]
            g.add((shape, SH.property, prop))
            g.add((prop, RDF.type, SH.PropertyShape))
            # no sh:message: SHACL makes a shape's message every result's, and "allowance: must be >= 0.0,
            # found -0.3" says more than the rule's text, which the report cites beside it anyway
            describe(prop, message=False)
            g.add((prop, SH.path, self.n.attribute(t.core.attribute.entity, t.core.attribute.name)))
            g.add((prop, SH.minCount, Literal(1)))
            value = t.core.value
            g.add((prop, SH[t.core.facet], Literal(value, datatype=XSD.integer if isinstance(value, int) else XSD.decimal)))
        else:
            assert t.sparql is not None
            c = BNode(f"{e.name}_{rule.label}")
            g.add((shape, SH.sparql, c))
            g.add((c, RDF.type, SH.SPARQLConstraint))
            g.add((c, SH.select, Literal(t.sparql)))
            g.add((c, SH.prefixes, URIRef(SHAPES_NS[:-1])))
        return shape

    # -- typed values -----------------------------------------------------------------------

    def add_typed_value(self, g: Graph, t: DefinedType) -> None:
        """A typed-value node ``[ a t ; p21:value v ]`` (a defined type inside a SELECT)."""
        shape = SHAPES[t.name]
        g.add((shape, RDF.type, SH.NodeShape))
        g.add((shape, SH.targetClass, self.n.declaration(t.name)))
        self.annotate(g, shape, t.name, t.name)
        prop = SHAPES[f"{t.name}.value"]
        g.add((shape, SH.property, prop))
        g.add((prop, RDF.type, SH.PropertyShape))
        g.add((prop, SH.path, P21.value))
        g.add((prop, SH.minCount, Literal(1)))
        g.add((prop, SH.maxCount, Literal(1)))
        self.annotate(g, prop, t.name, f"{t.name} value")
        self.add_value(g, prop, NamedType(t.name), t.name, None)
