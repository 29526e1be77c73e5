"""SHACL 4.8, the other constraint components: sh:closed, sh:hasValue, sh:in.
"""

from __future__ import annotations

from collections.abc import Mapping

from stepnc_graph.validation.component_base import (
    Compiling,
    Component,
    TRUE,
    Use,
    ValueComponent,
    Violation,
    found_text,
    local,
)
from stepnc_graph.validation.shapes import SH, ShapesGraph, UnsupportedShapes, sh


class ClosedComponent(Component):
    """sh:closed with sh:ignoredProperties (4.8.1): true (the literal only) allows only the
    predicates that are sh:path IRIs of the shape's property shapes, and the ignored ones. One
    result per other triple of a value node: its predicate is the result path, its object the value."""

    key, others, iri = "closed", ("ignoredProperties",), f"{SH}ClosedConstraintComponent"

    def allowed(self, c: Compiling, use: Use) -> list[str]:
        out = [p for prop in c.g.objects(use.shape, sh("property"))
               for p in c.g.objects(prop, sh("path")) if p.startswith("<")]
        if "ignoredProperties" in use.args:
            out += [p for p in c.g.items(use.args["ignoredProperties"]) if p.startswith("<")]
        return sorted(set(out))

    def _filter(self, c: Compiling, use: Use, p: str) -> str:
        allowed = self.allowed(c, use)
        return f"FILTER({p} NOT IN ({', '.join(allowed)}))" if allowed else ""

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        if use.args["closed"] != TRUE:
            return []
        if use.path is None:
            return [Violation(f"SELECT ?this ?path ?value WHERE {{ {focus} ?this ?path ?value "
                              f"{self._filter(c, use, '?path')} }}")]
        return [Violation(f"SELECT ?this ?path ?value WHERE {{ {focus} ?this {use.path} ?_v . ?_v ?path ?value "
                          f"{self._filter(c, use, '?path')} }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        if use.args["closed"] != TRUE:
            return "true"
        p, o = c.fresh("p"), c.fresh("o")
        if use.path is None:
            return f"NOT EXISTS {{ {v} {p} {o} {self._filter(c, use, p)} }}"
        x = c.fresh("pv")
        return f"NOT EXISTS {{ {v} {use.path} {x} . {x} {p} {o} {self._filter(c, use, p)} }}"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"a property the closed shape does not allow{found_text(value)}"


class HasValueComponent(Component):
    """sh:hasValue (4.8.2): the term is one of the value nodes (for a node shape: the focus node)."""

    key, iri = "hasValue", f"{SH}HasValueConstraintComponent"

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        arg = _value_term(use.args["hasValue"])
        if use.path is not None:
            return [Violation(f"SELECT ?this WHERE {{ {focus} FILTER NOT EXISTS {{ ?this {use.path} {arg} }} }}")]
        return [Violation(f"SELECT ?this WHERE {{ {focus} FILTER(!sameTerm(?this, {arg})) }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        arg = _value_term(use.args["hasValue"])
        return f"EXISTS {{ {v} {use.path} {arg} }}" if use.path is not None else f"sameTerm({v}, {arg})"

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        arg = _value_term(use.args["hasValue"])
        if use.path is None:
            return [f"FILTER(!sameTerm({v}, {arg}))"]
        m = c.fresh("m")
        return [f"OPTIONAL {{ {v} {use.path} {m} FILTER(sameTerm({m}, {arg})) }} FILTER(!bound({m}))"]

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must have the value {local(args['hasValue'])}"


def _value_term(term: str) -> str:
    """A shapes-graph term as a SPARQL constant (a blank node of the shapes graph is no data node)."""
    if term.startswith("_:"):
        raise UnsupportedShapes(f"a blank node ({term}) as the value of sh:hasValue or in sh:in")
    return term


class InComponent(ValueComponent):
    """sh:in (4.8.3): each value node is one of the listed terms."""

    key, iri = "in", f"{SH}InConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        items = [i for i in c.g.items(use.args["in"]) if not i.startswith("_:")]
        if not items:
            return "false"
        if all(i.startswith("<") for i in items):
            return f"({x} IN ({', '.join(items)}))"
        return "(" + " || ".join(f"sameTerm({x}, {i})" for i in items) + ")"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        items = ", ".join(local(i).split(".")[-1] for i in g.items(args["in"]))
        return f"must be one of {items}{found_text(value)}"
