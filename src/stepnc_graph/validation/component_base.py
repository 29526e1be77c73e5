"""The base of every SHACL constraint component: a use, the queries it compiles to, the Component
and ValueComponent classes, and what a component needs of the compiler (:class:`Compiling`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

from stepnc_graph.validation.shapes import IllFormedShapes, ShapesGraph, literal_text, sh


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


def int_parameter(term: str, where: str) -> int:
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
        return f"{self.iri.rsplit('#', 1)[-1]} not satisfied{found_text(value)}"


def found_text(value: str | None) -> str:
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
