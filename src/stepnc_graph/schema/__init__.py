"""The resolved schema model (entities, types, attributes, Part 21 order) and its builder."""

from stepnc_graph.schema.builder import build_model
from stepnc_graph.schema.errors import SchemaError, SchemaErrors
from stepnc_graph.schema.view import Part21Slot, SchemaModel

__all__ = ["Part21Slot", "SchemaError", "SchemaErrors", "SchemaModel", "build_model"]
