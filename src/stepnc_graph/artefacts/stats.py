"""Coverage of the ontology: EXPRESS counts next to counts read back from the Turtle.

The two sides are computed independently -- one from the resolved model, one
by querying the generated ``ontology/*.ttl`` files -- so a generator that drops
a declaration shows as a mismatch.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rdflib import Graph, URIRef, Variable

from stepnc_graph.schema.catalog import load_catalog_model

if TYPE_CHECKING:
    from stepnc_graph.generators.edition_shapes import EditionRule

_COUNT = """
PREFIX p21: <https://w3id.org/stepnc-graph/p21#>
PREFIX rdfs: <http://www.w3.org/2000/01/rdf-schema#>
SELECT
  (COUNT(DISTINCT ?entity) AS ?entities)
  (COUNT(DISTINCT ?type) AS ?types)
  (COUNT(DISTINCT ?attribute) AS ?attributes)
WHERE {
  { ?entity p21:expressKind "ENTITY" ; rdfs:isDefinedBy ?o }
  UNION
  { ?type p21:expressKind ?k ; rdfs:isDefinedBy ?o FILTER(?k != "ENTITY") }
  UNION
  { ?attribute p21:declaredBy ?d ; rdfs:isDefinedBy ?o }
}
"""


@dataclass(frozen=True)
class SchemaStats:
    schema: str
    express_entities: int
    express_types: int
    express_attributes: int
    owl_entities: int
    owl_types: int
    owl_attributes: int

    @property
    def complete(self) -> bool:
        return (self.express_entities, self.express_types, self.express_attributes) == (
            self.owl_entities, self.owl_types, self.owl_attributes)

    def asdict(self) -> dict[str, Any]:
        return {**asdict(self), "complete": self.complete}


def ontology_stats(root: Path) -> list[SchemaStats]:
    catalog, model = load_catalog_model(root / "ontology" / "express")
    out = []
    for name in sorted(model.schemas):
        decls = model.in_schema(name)
        entities = [d for d in decls if d.name in model.entities]
        g = Graph()
        ttl = root / "ontology" / f"{name}.ttl"
        if ttl.exists():
            g.parse(ttl, format="turtle")
        ontology = URIRef(catalog.ontology_base + name)
        binding = g.query(_COUNT, initBindings={"o": ontology}).bindings[0]
        row = [int(str(binding[Variable(v)])) for v in ("entities", "types", "attributes")]
        out.append(SchemaStats(
            schema=name,
            express_entities=len(entities),
            express_types=len(decls) - len(entities),
            express_attributes=sum(len(model.entity(e.name).attributes) for e in entities),
            owl_entities=row[0],
            owl_types=row[1],
            owl_attributes=row[2],
        ))
    return out


#: how the shapes generator's coverage begins the reason of a rule no instance can satisfy
DEFECT = "schema defect: "


@dataclass(frozen=True)
class RuleStats:
    """WHERE rules of one schema: how many became SHACL, and why the others did not."""

    schema: str
    total: int
    translated: int
    untranslated: tuple[tuple[str, str], ...]  # ("entity.wr1", reason)
    #: rules no instance can satisfy as written (schema defects): ("entity.wr1", what is done instead)
    defects: tuple[tuple[str, str], ...] = ()

    def asdict(self) -> dict[str, Any]:
        return {"schema": self.schema, "total": self.total, "translated": self.translated,
                "untranslated": [{"rule": r, "reason": why} for r, why in self.untranslated],
                "schema_defects": [{"rule": r, "what": why} for r, why in self.defects]}


def rule_stats(root: Path) -> list[RuleStats]:
    """Per schema, the WHERE rules the shapes generator translated (see generators/shacl.py)."""
    from stepnc_graph.generators.shacl import ShapesGenerator

    catalog, model = load_catalog_model(root / "ontology" / "express")
    coverage = ShapesGenerator(model, catalog).coverage()
    out = []
    for name in sorted(model.schemas):
        rules = [r for r in coverage if r.schema == name]
        if rules:
            out.append(RuleStats(name, len(rules), sum(r.translated for r in rules),
                                 tuple((f"{r.owner}.{r.label}", r.reason or "") for r in rules if not r.translated),
                                 tuple((f"{r.owner}.{r.label}", (r.reason or "").removeprefix(DEFECT))
                                       for r in rules if (r.reason or "").startswith(DEFECT))))
    return out


def edition_rule_stats(root: Path) -> list[EditionRule]:
    """Per edition beside the shipped one, each WHERE rule that differs from 2002 (as ``ontology
    build`` compares them) and what became of it: translated into ``shapes/edition_<edition>.ttl``
    (which shape), or not (why), and whether the 2002 rule is kept off the edition's instances."""
    from stepnc_graph.artefacts.build import edition_sources
    from stepnc_graph.generators.edition_shapes import edition_rules
    from stepnc_graph.mapping.editions import RENAMED
    from stepnc_graph.mapping.plans import Plans

    catalog, model = load_catalog_model(root / "ontology" / "express")
    base = Plans(model, catalog.naming)
    return [rule for e in edition_sources(catalog.directory, base)
            for rule in edition_rules(e.edition, e.catalog, e.model, model, e.naming, RENAMED.get(e.edition, {}))]
