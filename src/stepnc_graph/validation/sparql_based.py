"""SHACL 5 and 6, SHACL-SPARQL: sh:sparql constraints and SPARQL-based constraint components
(sh:validator, sh:nodeValidator, sh:propertyValidator), with the pre-binding of 5.3.1.
"""

from __future__ import annotations

from collections.abc import Mapping

from stepnc_graph.validation.component_base import Compiling, Component, TRUE, Use, Violation, found_text, local
from stepnc_graph.validation.shapes import IllFormedShapes, SH, ShapesGraph, UnsupportedShapes, literal_text, sh
from stepnc_graph.validation.sparql import Query, term_text


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
        return f"the SPARQL constraint found a problem{found_text(value)}"


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
        return f"{local(self.node)} not satisfied{found_text(value)}"


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
