"""How an EXPRESS attribute type appears in RDF -- one decision, used everywhere.

* simple types and defined types over them -> typed literals (``xsd:``);
  LOGICAL's UNKNOWN -> ``"UNKNOWN"^^p21:logicalUnknown``;
* entities, enumerations, SELECTs -> nodes (enumeration items are individuals);
* a top-level SET -> one triple per member (the natural form for SPARQL);
  an empty SET is recorded with ``p21:emptyAggregate``;
* LIST, ARRAY, BAG and every nested aggregate -> an ``rdf:List`` (keeps order
  and BAG duplicates, so the Part 21 round trip is lossless).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from rdflib import RDF, XSD, URIRef

from stepnc_graph.core.naming import Naming
from stepnc_graph.schema.model import AggregateType, BaseType, GenericType, NamedType, SimpleType, TypeRef
from stepnc_graph.schema.view import SchemaModel

XSD_OF: dict[BaseType, URIRef] = {
    BaseType.INTEGER: XSD.integer,
    BaseType.REAL: XSD.double,
    BaseType.NUMBER: XSD.double,
    BaseType.STRING: XSD.string,
    BaseType.BOOLEAN: XSD.boolean,
    BaseType.LOGICAL: XSD.boolean,
    BaseType.BINARY: XSD.hexBinary,
}

Form = Literal["literal", "node", "list", "repeated"]


@dataclass(frozen=True)
class ValueShape:
    """How values of one EXPRESS type are written in RDF.

    ``range`` is the XSD datatype (literals), the class (nodes) or ``rdf:List``;
    ``element`` describes members of lists and repeated values.
    """

    form: Form
    range: URIRef
    element: "ValueShape | None" = None
    aggregate: str | None = None
    logical: bool = False

    @property
    def leaf(self) -> "ValueShape":
        shape = self
        while shape.element is not None:
            shape = shape.element
        return shape


def _aggregate_text(t: AggregateType) -> str:
    text = str(t)
    return text[: text.rindex(" OF ")] if " OF " in text else text


def value_shape(model: SchemaModel, naming: Naming, t: TypeRef, top_level: bool = True) -> ValueShape:
    """The :class:`ValueShape` of type ``t`` (``top_level`` False inside aggregates)."""
    base = model.base_type(t)
    if isinstance(base, SimpleType):
        return ValueShape("literal", XSD_OF[base.base], logical=base.base is BaseType.LOGICAL)
    if isinstance(base, AggregateType):
        element = value_shape(model, naming, base.element, top_level=False)
        agg = _aggregate_text(base)
        if element.aggregate:
            agg = f"{agg} OF {element.aggregate}"
        if top_level and base.kind == "SET":
            return ValueShape("repeated", element.range if element.form != "list" else RDF.List,
                              element, agg, element.logical)
        return ValueShape("list", RDF.List, element, agg)
    if isinstance(base, NamedType):
        return ValueShape("node", naming.declaration(base.name))
    assert isinstance(base, GenericType)
    return ValueShape("node", URIRef("http://www.w3.org/2002/07/owl#Thing"))
