"""SHACL 4.3 and 4.4, value range and string-based constraint components: sh:min/maxExclusive,
sh:min/maxInclusive, sh:min/maxLength, sh:pattern, sh:languageIn, sh:uniqueLang.
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
    int_parameter,
)
from stepnc_graph.validation.shapes import SH, ShapesGraph, literal_text
from stepnc_graph.validation.sparql import term_text


class RangeComponent(ValueComponent):
    """sh:minExclusive, sh:minInclusive, sh:maxExclusive, sh:maxInclusive (4.3): each value node
    compares so with the bound; a value that does not compare (another type, not a literal) fails."""

    op: str = ""

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        return f"COALESCE({x} {self.op} {term_text(use.args[self.key])}, false)"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must be {self.op} {literal_text(args[self.key])}{found_text(value)}"


class MinExclusiveComponent(RangeComponent):
    key, iri, op = "minExclusive", f"{SH}MinExclusiveConstraintComponent", ">"


class MinInclusiveComponent(RangeComponent):
    key, iri, op = "minInclusive", f"{SH}MinInclusiveConstraintComponent", ">="


class MaxExclusiveComponent(RangeComponent):
    key, iri, op = "maxExclusive", f"{SH}MaxExclusiveConstraintComponent", "<"


class MaxInclusiveComponent(RangeComponent):
    key, iri, op = "maxInclusive", f"{SH}MaxInclusiveConstraintComponent", "<="


class LengthComponent(ValueComponent):
    """sh:minLength, sh:maxLength (4.4.1, 4.4.2): the string length of each value node (IRI or
    literal; a blank node fails)."""

    op: str = ""

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        n = int_parameter(use.args[self.key], use.shape)
        return f"(!isBlank({x}) && COALESCE(STRLEN(STR({x})) {self.op} {n}, false))"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        words = "at least" if self.op == ">=" else "at most"
        return f"must have {words} {literal_text(args[self.key])} characters{found_text(value)}"


class MinLengthComponent(LengthComponent):
    key, iri, op = "minLength", f"{SH}MinLengthConstraintComponent", ">="


class MaxLengthComponent(LengthComponent):
    key, iri, op = "maxLength", f"{SH}MaxLengthConstraintComponent", "<="


class PatternComponent(ValueComponent):
    """sh:pattern with sh:flags (4.4.3): the string of each value node matches the regular
    expression (a blank node fails)."""

    key, others, iri = "pattern", ("flags",), f"{SH}PatternConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        flags = use.args.get("flags")
        extra = f", {term_text(flags)}" if flags else ""
        return f"(!isBlank({x}) && COALESCE(REGEX(STR({x}), {term_text(use.args['pattern'])}{extra}), false))"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must match {literal_text(args['pattern'])}{found_text(value)}"


class LanguageInComponent(ValueComponent):
    """sh:languageIn (4.4.4): each value node is a literal whose language tag matches one of the
    listed ranges (basic filtering, langMatches)."""

    key, iri = "languageIn", f"{SH}LanguageInConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        ranges = c.g.items(use.args["languageIn"])
        if not ranges:
            return "false"
        tests = " || ".join(f"langMatches(lang({x}), {term_text(r)})" for r in ranges)
        return f"(isLiteral({x}) && ({tests}))"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must have a language in {', '.join(literal_text(r) for r in g.items(args['languageIn']))}" \
               f"{found_text(value)}"


class UniqueLangComponent(Component):
    """sh:uniqueLang (4.4.5): true (the literal true only) forbids two value nodes with the same
    language tag; one result per tag used twice. Property shapes only."""

    key, iri, applies_to = "uniqueLang", f"{SH}UniqueLangConstraintComponent", "property"

    def active(self, use: Use) -> bool:
        return use.args["uniqueLang"] == TRUE

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        if not self.active(use):
            return []
        return [Violation(f"SELECT DISTINCT ?this ?lang WHERE {{ {focus} ?this {use.path} ?_a . "
                          f"?this {use.path} ?_b . BIND(LCASE(lang(?_a)) AS ?lang) "
                          f"FILTER(!sameTerm(?_a, ?_b) && ?lang != \"\" && ?lang = LCASE(lang(?_b))) }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        if not self.active(use):
            return "true"
        a, b = c.fresh("a"), c.fresh("b")
        return (f"NOT EXISTS {{ {v} {use.path} {a} . {v} {use.path} {b} . FILTER(!sameTerm({a}, {b}) && "
                f"lang({a}) != \"\" && LCASE(lang({a})) = LCASE(lang({b}))) }}")

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return "two values share a language tag"
