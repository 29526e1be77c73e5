"""``ontology/generic.ttl`` and ``ontology/analysis.ttl``: the terms stepnc-graph adds for querying.

generic.ttl
    One property per EXPRESS attribute *name*, in its own namespace (``attr:``,
    since four attribute names -- identifier, path, placement, region -- are
    also class names in ``stepnc:``), and every per-entity property
    ``rdfs:subPropertyOf`` it: ``stepnc:executable.its_id`` and eight other
    ``its_id`` properties are all ``attr:its_id``. SPARQL engines do not apply
    sub-properties, so the loader materialises ``attr:`` values in each file's
    derived layer (:mod:`stepnc_graph.loading.derive`). A generic property is an
    ``owl:DatatypeProperty`` or an ``owl:ObjectProperty`` like its per-entity
    properties; for the few names whose per-entity properties are of both kinds
    (``diameter``: a length in one entity, a toleranced length in another) it is
    an ``owl:AnnotationProperty`` -- OWL 2 DL lets no IRI be both kinds, and
    annotations may hold literals and nodes alike, as the derived layer does --
    and the per-entity properties are sub-properties of ``attr:<name>.literal``
    or ``attr:<name>.node``, which it names with ``rdfs:seeAlso``.
analysis.ttl
    The analysis vocabulary (``sga:``) from :mod:`stepnc_graph.graphs.vocabulary_graph`:
    classes grouping ISO classes (roughing / finishing operations, ...), the
    derived-layer properties, and own-words definitions of the core entities.
"""

from __future__ import annotations

from collections import defaultdict

from rdflib import OWL, RDF, RDFS, XSD, Graph, Literal, URIRef
from rdflib.namespace import SKOS

from stepnc_graph.generators.owl import declare_annotations, is_data
from stepnc_graph.generators.rdfio import stable_turtle
from stepnc_graph.core.naming import (
    ANALYSIS_NS,
    ANALYSIS_ONTOLOGY,
    ATTRIBUTE_NS,
    ATTRIBUTE_ONTOLOGY,
    Naming,
    analysis_term,
    generic_attribute,
    generic_attribute_of_kind,
)
from stepnc_graph.schema.model import Attribute
from stepnc_graph.schema.view import SchemaModel
from stepnc_graph.vocabulary.typemap import value_shape
from stepnc_graph.vocabulary.analysis import ANALYSIS_CLASSES, ANALYSIS_PROPERTIES, CORE_DEFINITIONS, derived_entities


def attributes_by_name(model: SchemaModel) -> dict[str, list[Attribute]]:
    """Every attribute (explicit, derived, inverse) of every entity, grouped by name."""
    out: dict[str, list[Attribute]] = defaultdict(list)
    for entity in model.entities.values():
        for a in entity.attributes:
            out[a.name].append(a)
    return dict(sorted(out.items()))


class GenericVocabularyGenerator:
    """Builds ``generic.ttl`` and ``analysis.ttl`` from the model and the analysis definitions."""

    def __init__(self, model: SchemaModel, naming: Naming) -> None:
        self.model = model
        self.n = naming

    def outputs(self) -> dict[str, str]:
        return {"generic.ttl": stable_turtle(self.generic_graph()),
                "analysis.ttl": stable_turtle(self.analysis_graph())}

    def _graph(self) -> Graph:
        g = Graph()
        g.bind("stepnc", self.n.namespace)
        g.bind("attr", ATTRIBUTE_NS)
        g.bind("sga", ANALYSIS_NS)
        g.bind("owl", OWL)
        g.bind("skos", SKOS)
        return g

    def _is_data(self, a: Attribute) -> bool:
        return is_data(value_shape(self.model, self.n, a.type))

    def _ontology(self, iri: str, label: str, comment: str, imports: set[str]) -> tuple[Graph, URIRef]:
        """A new graph holding the ontology header of ``iri``, importing the ontologies of the
        ``imports`` schemas (those whose terms it uses: OWL tools check an ontology with its imports)."""
        g = self._graph()
        o = URIRef(iri)
        g.add((o, RDF.type, OWL.Ontology))
        g.add((o, RDFS.label, Literal(label)))
        g.add((o, RDFS.comment, Literal(comment)))
        for schema in sorted(imports):
            g.add((o, OWL.imports, self.n.ontology(schema)))
        return g, o

    def generic_graph(self) -> Graph:
        g, o = self._ontology(
            ATTRIBUTE_ONTOLOGY, "attribute",
            "Generic attribute properties of stepnc-graph: one per EXPRESS attribute name, each per-entity "
            "property of the ISO 14649 vocabulary a sub-property of it. Loaded files carry their values in "
            "their derived layer (<graph>/derived) for the process entities of the ISO 14649 schemas (not for "
            "ISO 10303 resources, toolpaths, tolerances and parameters).",
            set(self.model.schemas))
        derived = derived_entities(self.model)
        for name, attrs in attributes_by_name(self.model).items():
            p = generic_attribute(name)
            kinds = {self._is_data(a) for a in attrs}
            mixed = len(kinds) == 2
            g.add((p, RDF.type, OWL.AnnotationProperty if mixed else
                   OWL.DatatypeProperty if kinds == {True} else OWL.ObjectProperty))
            g.add((p, RDFS.label, Literal(name)))
            g.add((p, RDFS.isDefinedBy, o))
            owners = sorted({a.entity for a in attrs})
            stored = sorted({a.entity for a in attrs if a.kind == "explicit" and a.entity in derived})
            g.add((p, RDFS.comment, Literal(
                f"The attribute {name} of any entity ({', '.join(owners)}). "
                + (f"Materialised in derived layers for {', '.join(stored)}." if stored else
                   "Not materialised (declared by ISO 10303 resources, toolpaths, tolerances or parameters, or "
                   "derived/inverse): query the per-entity properties, or ?p rdfs:subPropertyOf this property.")
            )))
            for a in attrs:
                parent = self._kind_property(g, o, name, self._is_data(a)) if mixed else p
                g.add((self.n.attribute(a.entity, a.name), RDFS.subPropertyOf, parent))
                if mixed:
                    g.add((p, RDFS.seeAlso, parent))
        declare_annotations(g)
        return g

    def _kind_property(self, g: Graph, o: URIRef, name: str, data: bool) -> URIRef:
        """``attr:<name>.literal`` or ``attr:<name>.node``: the generic property of the attributes
        called ``name`` with values of one kind, where that name has both."""
        kind = "literal" if data else "node"
        p = generic_attribute_of_kind(name, kind)
        g.add((p, RDF.type, OWL.DatatypeProperty if data else OWL.ObjectProperty))
        g.add((p, RDFS.label, Literal(f"{name} ({kind})")))
        g.add((p, RDFS.isDefinedBy, o))
        g.add((p, RDFS.comment, Literal(
            f"The attribute {name} of the entities where its values are {'literals' if data else 'nodes'}; "
            f"attr:{name} (an annotation property: its derived-layer values are of both kinds) names this "
            "property with rdfs:seeAlso.")))
        return p

    def analysis_graph(self) -> Graph:
        g, o = self._ontology(
            ANALYSIS_ONTOLOGY, "analysis",
            "stepnc-graph's analysis vocabulary: what ISO 14649 leaves implicit (classes of roughing and "
            "finishing operations, thread cutting tools, the flattened execution order of a program), and "
            "own-words definitions of the core process entities. Not ISO terms.",
            {self.model.entity(m).schema for c in ANALYSIS_CLASSES for m in c.members}
            | {self.model.entity(name).schema for name in CORE_DEFINITIONS})
        for c in ANALYSIS_CLASSES:
            iri = analysis_term(c.name)
            g.add((iri, RDF.type, OWL.Class))
            g.add((iri, RDFS.label, Literal(c.label)))
            g.add((iri, RDFS.comment, Literal(c.comment)))
            g.add((iri, RDFS.isDefinedBy, o))
            for member in c.members:
                self.model.entity(member)  # a KeyError here is a typo in vocabulary.py
                g.add((self.n.declaration(member), RDFS.subClassOf, iri))
        for prop in ANALYSIS_PROPERTIES:
            iri = analysis_term(prop.name)
            g.add((iri, RDF.type, OWL.ObjectProperty if prop.kind == "object" else OWL.DatatypeProperty))
            g.add((iri, RDFS.label, Literal(prop.name)))
            g.add((iri, RDFS.comment, Literal(prop.comment)))
            g.add((iri, RDFS.isDefinedBy, o))
            if prop.domain:
                g.add((iri, RDFS.domain, analysis_term(prop.domain)))
            if prop.name in ("order", "index"):
                g.add((iri, RDFS.range, XSD.integer))
        for name, text in sorted(CORE_DEFINITIONS.items()):
            self.model.entity(name)
            g.add((self.n.declaration(name), SKOS.definition, Literal(text, lang="en")))
        declare_annotations(g)
        return g
