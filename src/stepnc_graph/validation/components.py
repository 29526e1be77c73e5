"""SHACL constraint components, one class each: its SPARQL forms, its default message, its clause.

A component turns one *use* (a shape and the values of its parameters) into:

* :meth:`Component.violations` -- SELECT queries run once over the data graph,
  one row (``?this``, maybe ``?value``, ``?path``) per validation result, with
  the focus nodes bound by the pattern the compiler gives (its targets);
* :meth:`Component.holds` -- a SPARQL boolean expression "focus node ``v``
  meets this use", for shapes nested in ``sh:node``, ``sh:not``, ``sh:and``,
  ``sh:or``, ``sh:xone`` and ``sh:qualifiedValueShape``;
* optionally :meth:`Component.witnesses` -- graph patterns, one per way ``v``
  can fail, which Oxigraph joins with the outer binding (a ``NOT EXISTS`` over
  a property path it evaluates without it: quadratic); None where only the
  boolean form exists.

The compiler (:mod:`.engine`) keeps targets, paths, nesting and the dispatch
over :data:`REGISTRY`; adding a component is adding a class here. Clauses are
those of the W3C SHACL Recommendation (2017).

Value nodes are the focus node itself for a node shape and the nodes its path
reaches for a property shape (SHACL 2.3.2); most components test each value
node on its own (:class:`ValueComponent`).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Protocol

from stepnc_graph.validation.shapes import (
    RDF_TYPE,
    SH,
    IllFormedShapes,
    ShapesGraph,
    UnsupportedShapes,
    literal_text,
    sh,
)
from stepnc_graph.validation.sparql import Query, term_text

XSD = "http://www.w3.org/2001/XMLSchema#"
TRUE = f'"true"^^<{XSD}boolean>'


class Compiling(Protocol):
    """What a component needs of the compiler."""

    g: ShapesGraph

    def fresh(self, stem: str = "x") -> str: ...
    def conforms(self, shape: str, v: str) -> str: ...
    def witnesses(self, shape: str, v: str) -> list[str] | None: ...
    def class_test(self, v: str, cls: str) -> str: ...
    def datatype_test(self, v: str, datatype: str) -> str: ...
    def path(self, term: str) -> str: ...
    def prefixes(self, node: str) -> dict[str, str]: ...
    def shapes_graph_iri(self) -> str: ...


@dataclass(frozen=True)
class Use:
    """One use of a component in a shape: the shape, its path (SPARQL text; None for a node
    shape) and the parameters' values (N-Triples terms, by local name)."""

    shape: str
    path: str | None
    path_term: str | None
    args: Mapping[str, str]


@dataclass(frozen=True)
class Violation:
    """A query finding the results of a use. ``excludes``: see :attr:`.engine.Check.excludes`."""

    query: str
    excludes: frozenset[str] | None = None
    node: str | None = None  # the SPARQL constraint or validator node (its messages)


def _int(term: str, where: str) -> int:
    try:
        return int(literal_text(term))
    except ValueError:
        raise IllFormedShapes(f"{where}: {term} is not an integer") from None


class Component:
    """A SHACL constraint component (SHACL 2.1.4): parameters, validation, message."""

    #: the parameter that makes a shape use the component (its local name in sh:)
    key: str = ""
    #: every other parameter it reads (optional ones included)
    others: tuple[str, ...] = ()
    #: the component's IRI
    iri: str = ""
    #: "node", "property" or "both": the shapes it applies to (on others it is ignored, as SHACL says)
    applies_to: str = "both"

    def uses(self, g: ShapesGraph, shape: str, path: str | None, path_term: str | None) -> list[Use]:
        """One use per value of the key parameter (other parameters: their value, if any)."""
        if (self.applies_to == "property" and path is None) or (self.applies_to == "node" and path is not None):
            return []
        out = []
        for value in g.objects(shape, sh(self.key)):
            args = {self.key: value}
            for p in self.others:
                v = g.value(shape, sh(p))
                if v is not None:
                    args[p] = v
            out.append(Use(shape, path, path_term, args))
        return out

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        raise NotImplementedError

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        raise NotImplementedError

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        return None

    def message(self, g: ShapesGraph, use_args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        """The result's text when its shape gives none (``shape``: the shape using the component)."""
        return f"{self.iri.rsplit('#', 1)[-1]} not satisfied{_found(value)}"


def _found(value: str | None) -> str:
    return f", found {value}" if value is not None else ""


def local(term: str) -> str:
    """A readable name: the text after the last ``#``, ``/`` or ``.`` of an IRI (an EXPRESS attribute
    ``entity.attr`` keeps its entity), a literal's lexical form."""
    if term.startswith('"'):
        return literal_text(term)
    text = term.strip("<>")
    for sep in ("#", "/"):
        if sep in text:
            text = text.rsplit(sep, 1)[1] or text
    return text


class ValueComponent(Component):
    """A component testing each value node on its own: :meth:`ok` is the test."""

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        raise NotImplementedError

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        values = f"?this {use.path} ?value ." if use.path is not None else "BIND(?this AS ?value)"
        return [Violation(f"SELECT ?this ?value WHERE {{ {focus} {values} FILTER(!({self.ok(c, use, '?value')})) }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        if use.path is None:
            return self.ok(c, use, v)
        x = c.fresh("pv")
        return f"NOT EXISTS {{ {v} {use.path} {x} . FILTER(!({self.ok(c, use, x)})) }}"

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        if use.path is None:
            return [f"FILTER(!({self.ok(c, use, v)}))"]
        x = c.fresh("pv")
        return [f"{v} {use.path} {x} . FILTER(!({self.ok(c, use, x)}))"]


# -- 4.1 value type -------------------------------------------------------------------------------


class ClassComponent(ValueComponent):
    """sh:class (4.1.1): each value node is a SHACL instance of the class (rdf:type, then
    rdfs:subClassOf in the data graph)."""

    key, iri = "class", f"{SH}ClassConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        return c.class_test(x, use.args["class"])

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must be a {local(args['class'])}{_found(value)}"


class DatatypeComponent(ValueComponent):
    """sh:datatype (4.1.2): each value node is a literal of the datatype, well-formed for it."""

    key, iri = "datatype", f"{SH}DatatypeConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        return c.datatype_test(x, use.args["datatype"])

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must be an {local(args['datatype'])} literal{_found(value)}"


NODE_KINDS = {
    "IRI": "isIRI({v})", "BlankNode": "isBlank({v})", "Literal": "isLiteral({v})",
    "BlankNodeOrIRI": "(isIRI({v}) || isBlank({v}))", "BlankNodeOrLiteral": "(isBlank({v}) || isLiteral({v}))",
    "IRIOrLiteral": "(isIRI({v}) || isLiteral({v}))",
}


class NodeKindComponent(ValueComponent):
    """sh:nodeKind (4.1.3): each value node is of the node kind."""

    key, iri = "nodeKind", f"{SH}NodeKindConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        kind = use.args["nodeKind"]
        name = kind[len(SH) + 1:-1] if kind.startswith(f"<{SH}") else ""
        if name not in NODE_KINDS:
            raise IllFormedShapes(f"{use.shape}: sh:nodeKind {kind} is not a SHACL node kind")
        return NODE_KINDS[name].format(v=x)

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must be a node of kind {local(args['nodeKind'])}{_found(value)}"


# -- 4.2 cardinality ------------------------------------------------------------------------------


class MinCountComponent(Component):
    """sh:minCount (4.2.1): at least n value nodes. Property shapes only."""

    key, iri, applies_to = "minCount", f"{SH}MinCountConstraintComponent", "property"

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        n = _int(use.args["minCount"], use.shape)
        if n <= 0:
            return []
        if n == 1:
            return [Violation(f"SELECT ?this WHERE {{ {focus} FILTER NOT EXISTS {{ ?this {use.path} ?_v }} }}")]
        return [Violation(f"SELECT ?this WHERE {{ {{ SELECT ?this (COUNT(DISTINCT ?_v) AS ?_n) WHERE {{ {focus} "
                          f"OPTIONAL {{ ?this {use.path} ?_v }} }} GROUP BY ?this }} FILTER(?_n < {n}) }}")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        return at_least(c, v, use.path or "", _int(use.args["minCount"], use.shape))

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        n = _int(use.args["minCount"], use.shape)
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
        n = _int(use.args["maxCount"], use.shape)
        return [Violation(f"SELECT ?this WHERE {{ {focus} ?this {use.path} ?_v }} GROUP BY ?this "
                          f"HAVING (COUNT(DISTINCT ?_v) > {n})")]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        return f"!{at_least(c, v, use.path or '', _int(use.args['maxCount'], use.shape) + 1)}"

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        xs = [c.fresh("c") for _ in range(_int(use.args["maxCount"], use.shape) + 1)]
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


# -- 4.3 value range, 4.4 string ----------------------------------------------------------------------


class RangeComponent(ValueComponent):
    """sh:minExclusive, sh:minInclusive, sh:maxExclusive, sh:maxInclusive (4.3): each value node
    compares so with the bound; a value that does not compare (another type, not a literal) fails."""

    op: str = ""

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        return f"COALESCE({x} {self.op} {term_text(use.args[self.key])}, false)"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must be {self.op} {literal_text(args[self.key])}{_found(value)}"


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
        n = _int(use.args[self.key], use.shape)
        return f"(!isBlank({x}) && COALESCE(STRLEN(STR({x})) {self.op} {n}, false))"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        words = "at least" if self.op == ">=" else "at most"
        return f"must have {words} {literal_text(args[self.key])} characters{_found(value)}"


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
        return f"must match {literal_text(args['pattern'])}{_found(value)}"


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
               f"{_found(value)}"


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


# -- 4.5 property pairs ------------------------------------------------------------------------------


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
        return f"must equal the values of {local(args['equals'])}{_found(value)}"


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
        return f"must not be a value of {local(args['disjoint'])}{_found(value)}"


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
        return f"must be {self.op} the values of {local(args[self.key])}{_found(value)}"


class LessThanOrEqualsComponent(LessThanComponent):
    """sh:lessThanOrEquals (4.5.4): as sh:lessThan, with equality allowed."""

    key, iri, op = "lessThanOrEquals", f"{SH}LessThanOrEqualsConstraintComponent", "<="


# -- 4.6 logical ----------------------------------------------------------------------------------------


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
        return f"must not conform to {local(args['not'])}{_found(value)}"


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
        return f"must conform to {self.wording}{_found(value)}"


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


# -- 4.7 shape-based ----------------------------------------------------------------------------------


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
        return f"must conform to {local(args['node'])}{_found(value)}"


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
        return _int(use.args[self.bound], use.shape)


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


# -- 4.8 other ------------------------------------------------------------------------------------------


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
        return f"a property the closed shape does not allow{_found(value)}"


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
        return f"must be one of {items}{_found(value)}"


# -- 5 SHACL-SPARQL ------------------------------------------------------------------------------------


#: variables SHACL pre-binds in a SPARQL constraint (5.3.1)
PREBOUND = ("this", "shapesGraph", "currentShape")


class SparqlComponent(Component):
    """sh:sparql (5.1-5.3): a SELECT whose solutions are the results, ``$this`` pre-bound to each
    focus node, ``$PATH`` the property shape's path, ``$currentShape`` the shape and ``$shapesGraph``
    a graph holding the shapes; ``?value`` and ``?path`` of a solution are the result's."""

    key, iri = "sparql", f"{SH}SPARQLConstraintComponent"

    def uses(self, g: ShapesGraph, shape: str, path: str | None, path_term: str | None) -> list[Use]:
        return [u for u in super().uses(g, shape, path, path_term) if g.value(u.args["sparql"], sh("deactivated")) != TRUE]

    def query(self, c: Compiling, use: Use) -> Query:
        node = use.args["sparql"]
        select = c.g.objects(node, sh("select"))
        if len(select) != 1 or not select[0].startswith('"'):
            raise IllFormedShapes(f"{node}: a SPARQL constraint needs exactly one sh:select (a string)")
        where = f"the SPARQL constraint {node} of {use.shape}"
        q = Query.parse(literal_text(select[0]), c.prefixes(node), where)
        if q.form() != "SELECT":
            raise IllFormedShapes(f"{where}: sh:select holds no SELECT query")
        q.refuse_forbidden(PREBOUND)
        return q.replace_path(use.path)

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        q, extra = _prebind_variables(c, self.query(c, use), use.shape)
        return [Violation(q.ensure_projected("?this").with_focus(lambda: focus + extra), node=use.args["sparql"])]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        return f"NOT EXISTS {{ {self.body(c, use, v)} }}"

    def witnesses(self, c: Compiling, use: Use, v: str) -> list[str] | None:
        return [self.body(c, use, v)]

    def body(self, c: Compiling, use: Use, v: str) -> str:
        return _prebind(c, self.query(c, use), use.shape, {}).substitute({"this": v}).where_body()

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"the SPARQL constraint found a problem{_found(value)}"


def _prebind_variables(c: Compiling, q: Query, shape: str) -> tuple[Query, str]:
    """``$this`` as ``?this``; ``$currentShape`` and ``$shapesGraph`` as variables bound by the
    returned ``VALUES`` text, which goes wherever the focus pattern goes (so ``bound($shapesGraph)``
    stays a variable test, as pre-binding makes it)."""
    names, terms = [], []
    if q.uses("currentShape"):
        if shape.startswith("_:"):
            raise UnsupportedShapes(f"{q.where}: $currentShape of a blank-node shape cannot be given to SPARQL")
        names.append("?currentShape")
        terms.append(shape)
    if q.uses("shapesGraph"):
        names.append("?shapesGraph")
        terms.append(c.shapes_graph_iri())
    q = q.substitute({"this": "?this", **{n[1:]: n for n in names}})
    extra = f" VALUES ({' '.join(names)}) {{ ({' '.join(terms)}) }}" if names else ""
    return q, extra


def _prebind(c: Compiling, q: Query, shape: str, params: Mapping[str, str]) -> Query:
    """``$currentShape``, ``$shapesGraph`` and parameters as constants; ``$this`` as ``?this``."""
    values: dict[str, str] = {"this": "?this"}
    if q.uses("currentShape"):
        if shape.startswith("_:"):
            raise UnsupportedShapes(f"{q.where}: $currentShape of a blank-node shape cannot be given to SPARQL")
        values["currentShape"] = shape
    if q.uses("shapesGraph"):
        values["shapesGraph"] = c.shapes_graph_iri()
    for name, term in params.items():
        values[name] = term_text(term)
    return q.substitute(values)


class CustomComponent(Component):
    """A SPARQL-based constraint component of the shapes graph (SHACL 6): ``sh:parameter`` paths are
    its parameters (pre-bound as ``$name``), ``sh:nodeValidator``/``sh:propertyValidator`` (SELECT)
    or ``sh:validator`` (ASK, ``$value`` pre-bound: true when the value node is fine) its validators."""

    def __init__(self, node: str, params: tuple[tuple[str, str, bool], ...], g: ShapesGraph) -> None:
        self.node = node
        self.params = params  # (path IRI, local name, optional)
        self.g = g
        self.iri = node.strip("<>")

    def uses(self, g: ShapesGraph, shape: str, path: str | None, path_term: str | None) -> list[Use]:
        args: dict[str, str] = {}
        for iri, name, optional in self.params:
            value = g.value(shape, iri)
            if value is None:
                if not optional:
                    return []
                continue
            args[name] = value
        if not args:
            return []
        return [Use(shape, path, path_term, args)] if self.validator(path) is not None else []

    def validator(self, path: str | None) -> tuple[str, str] | None:
        """(validator node, "select"|"ask") for a node shape (path None) or a property shape."""
        own = "nodeValidator" if path is None else "propertyValidator"
        for prop in (own, "validator"):
            for node in self.g.objects(self.node, sh(prop)):
                if self.g.value(node, sh("select")) is not None:
                    return node, "select"
                if self.g.value(node, sh("ask")) is not None:
                    return node, "ask"
        return None

    def query(self, c: Compiling, use: Use) -> tuple[str, Query, str]:
        found = self.validator(use.path)
        if found is None:
            raise IllFormedShapes(f"{self.node}: no validator for this kind of shape")
        node, kind = found
        text = self.g.value(node, sh(kind)) or ""
        where = f"the validator {node} of the component {self.node}"
        q = Query.parse(literal_text(text), c.prefixes(node), where)
        if q.form() != kind.upper():
            raise IllFormedShapes(f"{where}: sh:{kind} holds no {kind.upper()} query")
        names = [*PREBOUND, *(name for _, name, _ in self.params)] + (["value"] if kind == "ask" else [])
        q.refuse_forbidden(names)
        return node, _prebind(c, q.replace_path(use.path), use.shape, use.args), kind

    def violations(self, c: Compiling, use: Use, focus: str) -> list[Violation]:
        node, q, kind = self.query(c, use)
        if kind == "select":
            return [Violation(q.ensure_projected("?this").with_focus(lambda: focus), node=node)]
        body = q.substitute({"value": "?value"}).where_body()
        values = f"?this {use.path} ?value ." if use.path is not None else "BIND(?this AS ?value)"
        return [Violation(f"SELECT ?this ?value WHERE {{ {focus} {values} FILTER NOT EXISTS {{ {body} }} }}",
                          node=node)]

    def holds(self, c: Compiling, use: Use, v: str) -> str:
        node, q, kind = self.query(c, use)
        if kind == "select":
            return f"NOT EXISTS {{ {q.substitute({'this': v}).where_body()} }}"
        x = c.fresh("cv")
        body = q.substitute({"value": x, "this": v}).where_body()
        if use.path is None:
            body = q.substitute({"value": v, "this": v}).where_body()
            return f"EXISTS {{ {body} }}"
        return f"NOT EXISTS {{ {v} {use.path} {x} . FILTER NOT EXISTS {{ {body} }} }}"

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"{local(self.node)} not satisfied{_found(value)}"


def custom_components(g: ShapesGraph) -> list[CustomComponent]:
    """The SPARQL-based constraint components declared in the shapes graph."""
    out = []
    for node in sorted(g.instances_of(sh("ConstraintComponent"))):
        params = []
        for p in g.objects(node, sh("parameter")):
            path = g.value(p, sh("path"))
            if path is None or not path.startswith("<"):
                raise IllFormedShapes(f"{node}: a parameter without an IRI sh:path")
            optional = g.value(p, sh("optional")) == TRUE
            params.append((path, local(path), optional))
        if not params:
            raise IllFormedShapes(f"{node}: a constraint component without sh:parameter")
        out.append(CustomComponent(node=node, params=tuple(params), g=g))
    return out


#: the built-in components, in the order their checks are compiled
REGISTRY: tuple[Component, ...] = (
    ClassComponent(), DatatypeComponent(), NodeKindComponent(), InComponent(), HasValueComponent(),
    MinInclusiveComponent(), MaxInclusiveComponent(), MinExclusiveComponent(), MaxExclusiveComponent(),
    MinLengthComponent(), MaxLengthComponent(), PatternComponent(), LanguageInComponent(), NodeComponent(),
    NotComponent(), AndComponent(), OrComponent(), XoneComponent(), MinCountComponent(), MaxCountComponent(),
    UniqueLangComponent(), EqualsComponent(), DisjointComponent(), LessThanComponent(),
    LessThanOrEqualsComponent(), QualifiedMinCountComponent(), QualifiedMaxCountComponent(), ClosedComponent(),
    SparqlComponent(), PropertyComponent(),
)

#: sh: parameters of the built-in components
PARAMETERS = frozenset(p for comp in REGISTRY for p in (comp.key, *comp.others) if p)
#: sh: terms a shape may carry that constrain nothing (targets, path, annotations, severity ...)
NON_VALIDATING = frozenset({
    "targetClass", "targetNode", "targetSubjectsOf", "targetObjectsOf", "path", "severity", "message",
    "deactivated", "name", "description", "order", "group", "defaultValue", "prefixes", "declare", "select",
    "ask", "prefix", "namespace", "labelTemplate", "parameter", "validator", "nodeValidator",
    "propertyValidator", "optional", "resultAnnotation", "intersection", "detail",
})


