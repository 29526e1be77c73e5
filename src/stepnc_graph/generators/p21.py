"""The ``p21:`` meta vocabulary as ``ontology/p21.ttl``."""

from __future__ import annotations

from rdflib import OWL, RDF, RDFS, XSD, BNode, Graph, Literal, URIRef
from rdflib.collection import Collection

from stepnc_graph.generators.owl import SCHEMA_ANNOTATIONS
from stepnc_graph.generators.rdfio import stable_turtle
from stepnc_graph.core.naming import P21, P21_ONTOLOGY
from stepnc_graph.vocabulary.p21 import TERMS

_TYPES = {
    "annotation": OWL.AnnotationProperty,
    "data": OWL.DatatypeProperty,
    "object": OWL.ObjectProperty,
    "class": OWL.Class,
    "individual": OWL.NamedIndividual,
    "datatype": RDFS.Datatype,
}


class P21VocabularyGenerator:
    def __init__(self, version: str) -> None:
        self.version = version

    def outputs(self) -> dict[str, str]:
        g = Graph()
        g.bind("p21", str(P21))
        g.bind("owl", OWL)
        o = URIRef(P21_ONTOLOGY)
        g.add((o, RDF.type, OWL.Ontology))
        g.add((o, RDFS.label, Literal("p21")))
        g.add((o, OWL.versionInfo, Literal(self.version)))
        g.add((o, RDFS.comment, Literal(
            "Terms stepnc-graph uses to describe EXPRESS declarations (annotations on the ISO 14649 "
            "vocabulary) and Part 21 structure (on loaded instances).")))
        for term in TERMS:
            iri = P21[term.name]
            g.add((iri, RDF.type, _TYPES[term.kind]))
            g.add((iri, RDFS.label, Literal(term.name)))
            g.add((iri, RDFS.comment, Literal(term.comment)))
            g.add((iri, RDFS.isDefinedBy, o))
        define_logical_unknown(g)
        for annotation in SCHEMA_ANNOTATIONS:  # used by every schema ontology, which imports this one
            g.add((annotation, RDF.type, OWL.AnnotationProperty))
        return {"p21.ttl": stable_turtle(g)}


def define_logical_unknown(g: Graph) -> None:
    """``p21:logicalUnknown`` as the data range holding the one string "UNKNOWN".

    OWL 2 DL admits a datatype outside its datatype map when it is defined by a
    data range (a DatatypeDefinition, owl:equivalentClass in RDF); reasoners such
    as HermiT refuse one that is only declared.
    """
    node, members = BNode("logical_unknown_definition"), BNode("logical_unknown_values")
    g.add((node, RDF.type, RDFS.Datatype))
    Collection(g, members, [Literal("UNKNOWN", datatype=XSD.string)])
    g.add((node, OWL.oneOf, members))
    g.add((P21.logicalUnknown, OWL.equivalentClass, node))
