"""The WHERE rules of another edition of ISO 14649 where they differ from the shipped (2002) ones,
as shapes: ``shapes/edition_<edition>.ttl``.

The shipped shapes check a program of another edition through the vocabulary both share
(:mod:`stepnc_graph.mapping.editions`), but a rule that tests a term the edition has in its own
meaning (2001 ``ball_endmill`` WR4 tests ``tool_top_angle``, 2002 ``tool_tip_half_angle``) or a
rule one edition has and the other has not would be applied as 2002 has it. So the rules are
compared entity by entity (:func:`rule_differences`: the rule texts, with what does not change
their meaning set aside), and each rule of the edition that differs is compiled from the edition's
EXPRESS against the terms its loader writes (:class:`EditionNaming`) into a shape of its own that
says which edition it belongs to (``shapes:edition``) and which 2002 shape it stands in for
(``shapes:replaces``), and each 2002 rule shape whose rule the edition has otherwise or not at all
says which edition's instances it does not hold for (``shapes:notForEdition``).
:mod:`stepnc_graph.validation.editions` applies each to the instances of its edition only.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from rdflib import Literal, URIRef

from stepnc_graph.core.naming import Naming
from stepnc_graph.generators.express_sparql import Untranslatable, translate_rule
from stepnc_graph.generators.express_terms import express_text
from stepnc_graph.generators.rdfio import stable_turtle
from stepnc_graph.generators.shacl import SHAPES, ShapesGenerator
from stepnc_graph.mapping.plans import Plans
from stepnc_graph.schema.catalog import Catalog
from stepnc_graph.schema.view import SchemaModel

#: the file name of an edition's shapes in ``shapes/``
FILE = "edition_{edition}.ttl"

_SCHEMA_PREFIX = re.compile(r"'[a-z0-9_]+\.", re.IGNORECASE)  # 'MILLING_SCHEMA.ROUND_HOLE' -> 'ROUND_HOLE'
_SELF_DOT = re.compile(r"\bself\.", re.IGNORECASE)  # SELF.dimension: the attribute dimension of SELF


@dataclass(frozen=True)
class RuleDifference:
    """One WHERE rule that differs between an edition and the shipped one: the edition's entity
    and its 2002 counterpart, the rule's label and its EXPRESS text in each (None: not there)."""

    entity: str
    shipped_entity: str
    label: str
    edition_text: str | None
    shipped_text: str | None

    @property
    def kind(self) -> str:
        if self.shipped_text is None:
            return "edition only"
        return "2002 only" if self.edition_text is None else "differs"


def comparable_text(expr: Any) -> str:
    """A rule's text with what does not change its meaning set aside: the schema prefix of a
    TYPEOF string (each edition names its own schemas), ``SELF.`` before an attribute (an attribute
    named alone is SELF's), letter case (EXPRESS is case-insensitive outside strings, and the
    TYPEOF strings are compared case-insensitively)."""
    return _SELF_DOT.sub("", _SCHEMA_PREFIX.sub("'", express_text(expr))).lower()


def rule_differences(own: SchemaModel, shipped: SchemaModel, renamed: Mapping[str, str]) -> list[RuleDifference]:
    """Every WHERE rule of an entity of ``own`` (an edition's model) that the same entity of
    ``shipped`` (under its 2002 name: ``renamed``) does not have with the same meaning, and every
    rule of the 2002 entity the edition's lacks; entities only one edition has are left out (their
    rules have no counterpart to differ from). Sorted by entity and label."""
    out: list[RuleDifference] = []
    for name, entity in sorted(own.entities.items()):
        counterpart = shipped.entities.get(renamed.get(name, name))
        if counterpart is None:
            continue
        mine = {r.label.upper(): r for r in entity.where_rules}
        theirs = {r.label.upper(): r for r in counterpart.where_rules}
        for label in sorted(set(mine) | set(theirs)):
            a, b = mine.get(label), theirs.get(label)
            if a is not None and b is not None and comparable_text(a.expr) == comparable_text(b.expr):
                continue
            out.append(RuleDifference(name, counterpart.name, label,
                                      express_text(a.expr) if a is not None else None,
                                      express_text(b.expr) if b is not None else None))
    return out


@dataclass(frozen=True)
class EditionNaming(Naming):
    """The shipped naming, except that an attribute of the edition's model is named by the property
    the edition's loader writes for it: the 2002 one where it means the same, else its own."""

    written: Mapping[tuple[str, str], str] = field(default_factory=dict, hash=False, compare=False)

    def attribute_iri(self, entity: str, attribute: str) -> str:
        return self.written.get((entity.lower(), attribute.lower())) or super().attribute_iri(entity, attribute)


def edition_naming(base: Naming, own: Plans, plans: Plans) -> EditionNaming:
    """The :class:`EditionNaming` of an edition from its own plans (its attributes by the entity
    that declares them) and the plans its loader reads with (``plans``: the same slots, in the same
    order, each holding the property it writes)."""
    written: dict[tuple[str, str], str] = {}
    for key, mine in own.entities.items():
        loaded = plans.entities.get(key)
        if loaded is None:
            continue
        for slot, used in zip(mine.slots, loaded.slots, strict=True):
            written.setdefault((slot.entity.lower(), slot.name.lower()), used.prop)
    return EditionNaming(namespace=base.namespace, ontology_base=base.ontology_base, written=written)


def edition_shapes(edition: str, catalog: Catalog, own: SchemaModel, shipped: SchemaModel,
                   naming: EditionNaming, renamed: Mapping[str, str]) -> str:
    """``shapes/edition_<edition>.ttl``: the edition's rules that differ from 2002, compiled from
    its EXPRESS (``own``, parsed expressions) against the terms its loader writes (``naming``)."""
    generator = ShapesGenerator(own, catalog, naming, shape_prefix=f"{edition}.")
    g = generator.new_graph()
    for d in rule_differences(own, shipped, renamed):
        shipped_shape = _shipped_shape(shipped, naming, d)
        if shipped_shape is not None:  # the 2002 rule does not hold for this edition's instances
            g.add((shipped_shape, SHAPES.notForEdition, Literal(edition)))
        if d.edition_text is None:
            continue
        entity = own.entities[d.entity]
        rule = next(r for r in entity.where_rules if r.label.upper() == d.label)
        shape = generator.add_rule(g, entity, rule)
        if shape is None:
            continue  # not translated: neither edition's rule is checked on its instances
        g.add((shape, SHAPES.edition, Literal(edition)))
        if shipped_shape is not None:
            g.add((shape, SHAPES.replaces, shipped_shape))
    return stable_turtle(g)



@dataclass(frozen=True)
class EditionRule:
    """What becomes of one WHERE rule that differs between an edition and 2002 (:class:`RuleDifference`):
    its ``kind`` (``differs``, ``edition only``, ``2002 only``), the edition's shape that checks it on
    the edition's instances (None: not translated, or the edition has no such rule) with ``reason``
    why not (or, for a schema defect whose intent the shape checks, what it checks), and whether the
    2002 rule's shape is kept off those instances (``shapes:notForEdition``)."""

    edition: str
    entity: str
    label: str
    kind: str
    shape: str | None
    reason: str | None
    shipped_withheld: bool

    @property
    def rule(self) -> str:
        return f"{self.entity}.{self.label.lower()}"

    def asdict(self) -> dict[str, Any]:
        return {"edition": self.edition, "rule": self.rule, "kind": self.kind, "translated": self.shape is not None,
                "shape": self.shape, "reason": self.reason, "shipped_rule_withheld": self.shipped_withheld}


def edition_rules(edition: str, catalog: Catalog, own: SchemaModel, shipped: SchemaModel,
                  naming: EditionNaming, renamed: Mapping[str, str]) -> list[EditionRule]:
    """Each rule of :func:`rule_differences` and what :func:`edition_shapes` makes of it (the same
    generator, so the same translations): for ``ontology stats`` and the docs."""
    generator = ShapesGenerator(own, catalog, naming, shape_prefix=f"{edition}.")
    coverage = {(c.owner, c.label.upper()): c for c in generator.coverage()}
    out = []
    for d in rule_differences(own, shipped, renamed):
        withheld = _shipped_shape(shipped, naming, d) is not None
        c = coverage.get((d.entity, d.label)) if d.edition_text is not None else None
        if c is None:
            out.append(EditionRule(edition, d.entity, d.label, d.kind, None,
                                   f"{edition} has no such rule" if d.edition_text is None else "not compiled",
                                   withheld))
            continue
        shape = f"shapes:{edition}.{d.entity}-{d.label.lower()}" if c.translated else None
        out.append(EditionRule(edition, d.entity, d.label, d.kind, shape, c.reason, withheld))
    return out


def _shipped_shape(shipped: SchemaModel, naming: Naming, d: RuleDifference) -> URIRef | None:
    """The shape the shipped shapes check the 2002 rule of ``d`` with (named as the shapes
    generator names it), or None when 2002 has no such rule or does not translate it."""
    entity = shipped.entities[d.shipped_entity]
    rule = next((r for r in entity.where_rules if r.label.upper() == d.label), None)
    if rule is None:
        return None
    try:
        translate_rule(shipped, Naming(naming.namespace, naming.ontology_base), entity, rule.expr)
    except Untranslatable:
        return None
    return SHAPES[f"{entity.name}-{rule.label}"]
