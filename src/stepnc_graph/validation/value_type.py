"""SHACL 4.1, value type constraint components: sh:class, sh:datatype, sh:nodeKind.
"""

from __future__ import annotations

from collections.abc import Mapping

from stepnc_graph.validation.component_base import Compiling, Use, ValueComponent, found_text, local
from stepnc_graph.validation.shapes import IllFormedShapes, SH, ShapesGraph


class ClassComponent(ValueComponent):
    """sh:class (4.1.1): each value node is a SHACL instance of the class (rdf:type, then
    rdfs:subClassOf in the data graph)."""

    key, iri = "class", f"{SH}ClassConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        return c.class_test(x, use.args["class"])

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must be a {local(args['class'])}{found_text(value)}"


class DatatypeComponent(ValueComponent):
    """sh:datatype (4.1.2): each value node is a literal of the datatype, well-formed for it."""

    key, iri = "datatype", f"{SH}DatatypeConstraintComponent"

    def ok(self, c: Compiling, use: Use, x: str) -> str:
        return c.datatype_test(x, use.args["datatype"])

    def message(self, g: ShapesGraph, args: Mapping[str, str], value: str | None, shape: str = "") -> str:
        return f"must be an {local(args['datatype'])} literal{found_text(value)}"


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
        return f"must be a node of kind {local(args['nodeKind'])}{found_text(value)}"
