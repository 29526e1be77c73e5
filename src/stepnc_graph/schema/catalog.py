"""The project's ISO 14649 schemas: read ``ontology/express/schemas.toml`` and build the model.

:func:`iso14649` reads the compiled model (:mod:`stepnc_graph.schema.cache`);
the EXPRESS parser and the builder are imported only when the model is built
from the EXPRESS (:mod:`stepnc_graph.schema.catalog_file`, whose names are here too).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from stepnc_graph.schema.catalog_file import (
    EDITIONS,
    Catalog,
    edition_directory,
    load_catalog_model,
    load_edition_model,
    parse_catalog,
    read_catalog,
)

if TYPE_CHECKING:
    from stepnc_graph.schema.view import SchemaModel

__all__ = ["EDITIONS", "Catalog", "edition_directory", "iso14649", "load_catalog_model", "load_edition_model",
           "parse_catalog", "read_catalog"]


def iso14649() -> tuple[Catalog, SchemaModel]:
    """The shipped ISO 14649 model, read once per process from the compiled model.

    A missing or stale compiled model is rebuilt from the EXPRESS with a
    :class:`~stepnc_graph.schema.cache.CompiledModelWarning`.
    """
    from stepnc_graph.schema.cache import shipped

    compiled = shipped()
    return compiled.catalog, compiled.model
