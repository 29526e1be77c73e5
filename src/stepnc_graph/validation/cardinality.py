"""SHACL 4.2, cardinality constraint components: sh:minCount, sh:maxCount.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping

from stepnc_graph.validation.component_base import Compiling, Component, Use, Violation, int_parameter
from stepnc_graph.validation.shapes import SH, ShapesGraph, UnsupportedShapes, literal_text


class MinCountComponent(Component):
    """sh:minCount (4.2.1): at least n value nodes. Property shapes only."""

    key, iri, applies_to = "minCount", f"{SH}MinCountConstraintComponent", "property"

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        n = int_parameter(use.args["minCount"], use.shape)
        if n <= 0:
            return []
        if n == 1:
            return [Violation(f"SELECT ?this WHERE {{ {focus} FILTER NOT EXISTS {{ ?this {use.path} ?_v }} }}")]
        return [Violation(f"SELECT ?this WHERE {{ {{ SELECT ?this (COUNT(DISTINCT ?_v) AS ?_n) WHERE {{ {focus} "
                          f"OPTIONAL {{ ?this {use.path} ?_v }} }} GROUP BY ?this }} FILTER(?_n < {n}) }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        return at_least(c, v, use.path or "", int_parameter(use.args["minCount"], use.shape))

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        n = int_parameter(use.args["minCount"], use.shape)
        if n > 1:
            return None
        if n <= 0:
            return []
        x = c.fresh("m")
        return [f"OPTIONAL {{ {v} {use.path} {x} }} FILTER(!bound({x}))"]

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        n = int(literal_text(args["minCount"]))
        return "required, found none" if n == 1 else f"at least {n} values required"


class MaxCountComponent(Component):
    """sh:maxCount (4.2.2): at most n value nodes. Property shapes only."""

    key, iri, applies_to = "maxCount", f"{SH}MaxCountConstraintComponent", "property"

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        n = int_parameter(use.args["maxCount"], use.shape)
        return [Violation(f"SELECT ?this WHERE {{ {focus} ?this {use.path} ?_v }} GROUP BY ?this "
                          f"HAVING (COUNT(DISTINCT ?_v) > {n})")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        return f"!{at_least(c, v, use.path or '', int_parameter(use.args['maxCount'], use.shape) + 1)}"

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        xs = [c.fresh("c") for _ in range(int_parameter(use.args["maxCount"], use.shape) + 1)]
        distinct = " && ".join(f"!sameTerm({a}, {b})" for a, b in itertools.combinations(xs, 2))
        return [" ".join(f"{v} {use.path} {x} ." for x in xs) + (f" FILTER({distinct})" if distinct else "")]

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"at most {literal_text(args['maxCount'])} value(s) allowed"


def at_least(c: Compiling, v: str, path: str, n: int, condition: Callable[[str], str] | None = None) -> str:
    """SPARQL boolean: ``v`` has at least ``n`` distinct values on ``path`` (each meeting
    ``condition(x)``). Written with n variables: refused above 8."""
    if n <= 0:
        return "true"
    if n > 8:
        raise UnsupportedShapes(f"a count above 8 ({n}) inside a nested shape (sh:node, sh:not, sh:and, sh:or, "
                                f"sh:xone, sh:qualifiedValueShape) is not compiled")
    xs = [c.fresh("c") for _ in range(n)]
    pattern = " ".join(f"{v} {path} {x} ." for x in xs)
    tests = [f"!sameTerm({a}, {b})" for a, b in itertools.combinations(xs, 2)]
    if condition:
        tests += [f"({condition(x)})" for x in xs]
    test = f" FILTER({' && '.join(tests)})" if tests else ""
    return f"EXISTS {{ {pattern}{test} }}"
