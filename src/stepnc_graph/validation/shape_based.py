"""SHACL 4.7, shape-based constraint components: sh:node, sh:property, sh:qualifiedValueShape.
"""

from __future__ import annotations

from collections.abc import Mapping

from stepnc_graph.validation.cardinality import at_least
from stepnc_graph.validation.component_base import (
    Compiling,
    Component,
    TRUE,
    Use,
    ValueComponent,
    Violation,
    found_text,
    int_parameter,
    local,
)
from stepnc_graph.validation.shapes import SH, ShapesGraph, literal_text, sh


class NodeComponent(ValueComponent):
    """sh:node (4.7.1): each value node conforms to the node shape. Run as one query per way the
    nested shape can fail where it can be said so (:meth:`Component.witnesses`)."""

    key, iri = "node", f"{SH}NodeConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        return c.conforms(use.args["node"], x)

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        patterns = c.witnesses(use.args["node"], "?value")
        if patterns is None:
            return super().violations(c, use, focus)
        values = f"?this {use.path} ?value ." if use.path is not None else "BIND(?this AS ?value)"
        return [Violation(f"SELECT DISTINCT ?this ?value WHERE {{ {focus} {values} {w} }}") for w in patterns]

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        if use.path is None:
            return c.witnesses(use.args["node"], v)
        x = c.fresh("pv")
        inner = c.witnesses(use.args["node"], x)
        return None if inner is None else [f"{v} {use.path} {x} . {w}" for w in inner]

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        comment = g.value(args["node"], "<http://www.w3.org/2000/01/rdf-schema#comment>")
        if comment:
            text = literal_text(comment).rstrip(".")
            return f"must be a{text[1:]}" if text.startswith("A ") else text
        kind = g.value(shape, "<https://w3id.org/stepnc-graph/p21#expressType>") if shape else None
        if kind:  # a generated list-members shape: the attribute's EXPRESS type says what the members are
            return f"list members must fit {literal_text(kind)}"
        return f"must conform to {local(args['node'])}{found_text(value)}"


class PropertyComponent(Component):
    """sh:property (4.7.2): each value node conforms to the property shape. Its results are the
    property shape's own, with the value node as focus node (the compiler nests its checks)."""

    key, iri = "property", f"{SH}PropertyConstraintComponent"

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        if use.path is None:
            return c.conforms(use.args["property"], v)
        x = c.fresh("pv")
        return f"NOT EXISTS {{ {v} {use.path} {x} . FILTER(!({c.conforms(use.args['property'], x)})) }}"

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        if use.path is None:
            return c.witnesses(use.args["property"], v)
        x = c.fresh("pv")
        inner = c.witnesses(use.args["property"], x)
        return None if inner is None else [f"{v} {use.path} {x} . {w}" for w in inner]


class QualifiedComponent(Component):
    """sh:qualifiedValueShape with sh:qualifiedMinCount / sh:qualifiedMaxCount (4.7.3): the number
    of value nodes conforming to the shape (and, with sh:qualifiedValueShapesDisjoint true, to no
    sibling qualified shape) is within the bound. Property shapes only."""

    key, applies_to = "qualifiedValueShape", "property"
    others = ("qualifiedMinCount", "qualifiedMaxCount", "qualifiedValueShapesDisjoint")
    bound: str = ""

    def uses(self, g: ShapesGraph, shape: str, path: str | None, path_term: str | None) -> list[Use]:
        return [u for u in super().uses(g, shape, path, path_term) if self.bound in u.args]

    def condition(self, c: Compiling, use: Use, x: str) -> str:
        tests = [c.conforms(use.args["qualifiedValueShape"], x)]
        if use.args.get("qualifiedValueShapesDisjoint") == TRUE:
            tests += [f"!{c.conforms(s, x)}" for s in siblings(c.g, use.shape, use.args["qualifiedValueShape"])]
        return " && ".join(tests)

    def count(self, c: Compiling, use: Use, focus: str) -> str:
        return (f"{{ SELECT ?this (COUNT(DISTINCT ?_q) AS ?_n) WHERE {{ {focus} OPTIONAL {{ ?this {use.path} ?_q "
                f"FILTER({self.condition(c, use, '?_q')}) }} }} GROUP BY ?this }}")

    def n(self, use: Use) -> int:
        return int_parameter(use.args[self.bound], use.shape)


class QualifiedMinCountComponent(QualifiedComponent):
    iri, bound = f"{SH}QualifiedMinCountConstraintComponent", "qualifiedMinCount"

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        return [Violation(f"SELECT ?this WHERE {{ {self.count(c, use, focus)} FILTER(?_n < {self.n(use)}) }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        return at_least(c, v, use.path or "", self.n(use), lambda x: self.condition(c, use, x))

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"at least {literal_text(args['qualifiedMinCount'])} value(s) must conform to " \
               f"{local(args['qualifiedValueShape'])}"


class QualifiedMaxCountComponent(QualifiedComponent):
    iri, bound = f"{SH}QualifiedMaxCountConstraintComponent", "qualifiedMaxCount"

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        return [Violation(f"SELECT ?this WHERE {{ {self.count(c, use, focus)} FILTER(?_n > {self.n(use)}) }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        return f"!{at_least(c, v, use.path or '', self.n(use) + 1, lambda x: self.condition(c, use, x))}"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"at most {literal_text(args['qualifiedMaxCount'])} value(s) may conform to " \
               f"{local(args['qualifiedValueShape'])}"


def siblings(g: ShapesGraph, shape: str, own: str) -> list[str]:
    """The sibling qualified value shapes of a property shape (4.7.3): those of the other property
    shapes of every shape that has it as sh:property."""
    out: list[str] = []
    for parent in g.subjects(sh("property"), shape):
        for prop in g.objects(parent, sh("property")):
            for q in g.objects(prop, sh("qualifiedValueShape")):
                if q != own and q not in out:
                    out.append(q)
    return out
