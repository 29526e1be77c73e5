"""SHACL 4.5, property pair constraint components: sh:equals, sh:disjoint, sh:lessThan,
sh:lessThanOrEquals.
"""

from __future__ import annotations

from collections.abc import Mapping

from stepnc_graph.validation.component_base import Compiling, Component, Use, Violation, found_text, local
from stepnc_graph.validation.shapes import SH, ShapesGraph


def _values(use: Use, v: str, x: str) -> str:
    """Pattern binding ``x`` to the value nodes of focus ``v``."""
    return f"{v} {use.path} {x} ." if use.path is not None else f"BIND({v} AS {x})"


class EqualsComponent(Component):
    """sh:equals (4.5.1): the value nodes and the values of the property are the same set; each
    node in one and not the other is a result."""

    key, iri = "equals", f"{SH}EqualsConstraintComponent"

    def _patterns(self, use: Use, v: str, x: str) -> tuple[str, str]:
        p = use.args["equals"]
        return (f"{_values(use, v, x)} FILTER NOT EXISTS {{ {v} {p} {x} }}",
                f"{v} {p} {x} . FILTER NOT EXISTS {{ {_values(use, v, x)} }}" if use.path is not None
                else f"{v} {p} {x} . FILTER(!sameTerm({x}, {v}))")

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        a, b = self._patterns(use, "?this", "?value")  # each branch binds its focus: a group sees no outer binding
        return [Violation(f"SELECT DISTINCT ?this ?value WHERE {{ {{ {focus} {a} }} UNION {{ {focus} {b} }} }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        x = c.fresh("e")
        a, b = self._patterns(use, v, x)
        return f"(NOT EXISTS {{ {a} }} && NOT EXISTS {{ {b} }})"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must equal the values of {local(args['equals'])}{found_text(value)}"


class DisjointComponent(Component):
    """sh:disjoint (4.5.2): no value node is a value of the property."""

    key, iri = "disjoint", f"{SH}DisjointConstraintComponent"

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        p = use.args["disjoint"]
        return [Violation(f"SELECT DISTINCT ?this ?value WHERE {{ {focus} {_values(use, '?this', '?value')} "
                          f"?this {p} ?value }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        x = c.fresh("d")
        return f"NOT EXISTS {{ {_values(use, v, x)} {v} {use.args['disjoint']} {x} }}"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must not be a value of {local(args['disjoint'])}{found_text(value)}"


class LessThanComponent(Component):
    """sh:lessThan (4.5.3): each value node is below every value of the property; a pair that does
    not compare is a result too. Property shapes only."""

    key, iri, applies_to = "lessThan", f"{SH}LessThanConstraintComponent", "property"
    op = "<"

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        # one result per pair (value node, value of the other property) that does not compare so
        return [Violation(f"SELECT DISTINCT ?this ?value ?other WHERE {{ {focus} ?this {use.path} ?value . "
                          f"?this {use.args[self.key]} ?other FILTER(!COALESCE(?value {self.op} ?other, false)) }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        x, o = c.fresh("l"), c.fresh("o")
        return (f"NOT EXISTS {{ {v} {use.path} {x} . {v} {use.args[self.key]} {o} "
                f"FILTER(!COALESCE({x} {self.op} {o}, false)) }}")

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must be {self.op} the values of {local(args[self.key])}{found_text(value)}"


class LessThanOrEqualsComponent(LessThanComponent):
    """sh:lessThanOrEquals (4.5.4): as sh:lessThan, with equality allowed."""

    key, iri, op = "lessThanOrEquals", f"{SH}LessThanOrEqualsConstraintComponent", "<="
