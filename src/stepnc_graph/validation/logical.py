"""SHACL 4.6, logical constraint components: sh:not, sh:and, sh:or, sh:xone.
"""

from __future__ import annotations

from collections.abc import Mapping

from stepnc_graph.validation.component_base import Compiling, Use, ValueComponent, Violation, found_text, local
from stepnc_graph.validation.shapes import RDF_TYPE, SH, ShapesGraph, sh


class NotComponent(ValueComponent):
    """sh:not (4.6.1): no value node conforms to the shape."""

    key, iri = "not", f"{SH}NotConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        return f"!{c.conforms(use.args['not'], x)}"

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        [v] = super().violations(c, use, focus)
        excluded = excluded_classes(c.g, use.args["not"]) if use.path is None else None
        return [Violation(v.query, excludes=excluded)]

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must not conform to {local(args['not'])}{found_text(value)}"


def excluded_classes(g: ShapesGraph, shape: str) -> frozenset[str] | None:
    """When ``shape`` is ``sh:class`` or ``sh:or`` of ``sh:class`` only: every class it admits by the
    data files' hierarchy; None for any other shape. Then ``sh:not shape`` on a node with one
    rdf:type fails only if that type is one of them (:attr:`.engine.Check.excludes`)."""
    alternatives = [shape]
    ors = g.objects(shape, sh("or"))
    if ors:
        alternatives = g.items(ors[0])
        if set(g.predicates(shape)) - {RDF_TYPE} != {sh("or")}:
            return None
    admitted: set[str] = set()
    for alt in alternatives:
        if set(g.predicates(alt)) - {RDF_TYPE} != {sh("class")}:
            return None
        admitted |= g.closure(g.objects(alt, sh("class"))[0])
    return frozenset(admitted)


class ListComponent(ValueComponent):
    """sh:and, sh:or, sh:xone (4.6.2-4.6.4): each value node conforms to all, some, exactly one
    of the listed shapes. A subclass says how the members' tests combine, what an empty list
    gives and, for the message, which of the shapes the node must conform to."""

    empty: str = "false"
    wording: str = ""

    def members(self, c: Compiling, use: Use, x: str) -> list[str]:
        return [c.conforms(s, x) for s in c.g.items(use.args[self.key])]

    def combined(self, tests: list[str]) -> str:
        raise NotImplementedError

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        m = self.members(c, use, x)
        return self.combined(m) if m else self.empty

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must conform to {self.wording}{found_text(value)}"


class AndComponent(ListComponent):
    key, iri = "and", f"{SH}AndConstraintComponent"
    empty, wording = "true", "every listed shape"

    def combined(self, tests: list[str]) -> str:
        return "(" + " && ".join(tests) + ")"


class OrComponent(ListComponent):
    key, iri = "or", f"{SH}OrConstraintComponent"
    wording = "one of the listed shapes"

    def combined(self, tests: list[str]) -> str:
        return "(" + " || ".join(tests) + ")"


class XoneComponent(ListComponent):
    key, iri = "xone", f"{SH}XoneConstraintComponent"
    wording = "exactly one of the listed shapes"

    def combined(self, tests: list[str]) -> str:
        return f"(({' + '.join(f'IF({t}, 1, 0)' for t in tests)}) = 1)"
