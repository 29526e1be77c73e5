"""The resolved schema model (entities, types, attributes, Part 21 order) and its builder.

The names below are imported on first use (module ``__getattr__``): the
builder pulls in the EXPRESS parser, which a command reading the compiled
model (:mod:`stepnc_graph.schema.cache`) never needs.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from stepnc_graph.schema.builder import build_model
    from stepnc_graph.schema.errors import SchemaError, SchemaErrors
    from stepnc_graph.schema.view import Part21Slot, SchemaModel

__all__ = ["Part21Slot", "SchemaError", "SchemaErrors", "SchemaModel", "build_model"]

_HOME = {"build_model": "builder", "SchemaError": "errors", "SchemaErrors": "errors",
         "Part21Slot": "view", "SchemaModel": "view"}


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(f"{__name__}.{_HOME[name]}"), name)
    globals()[name] = value
    return value
