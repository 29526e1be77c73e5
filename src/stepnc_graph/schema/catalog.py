"""The project's ISO 14649 schemas: read ``ontology/express/schemas.toml`` and build the model."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stepnc_graph.express.parser import ParsedSchema, parse_file
from stepnc_graph.resources import express_dir
from stepnc_graph.schema.builder import build_model
from stepnc_graph.schema.view import SchemaModel

if TYPE_CHECKING:
    from stepnc_graph.naming import Naming


@dataclass(frozen=True)
class Catalog:
    """What ``schemas.toml`` says: files in load order, metadata per schema, IRIs."""

    directory: Path
    files: tuple[str, ...]
    schemas: dict[str, dict[str, Any]]
    namespace: str
    ontology_base: str
    ontology_version: str

    @property
    def naming(self) -> "Naming":
        """IRI minting for this catalogue's namespace."""
        from stepnc_graph.naming import Naming

        return Naming(self.namespace, self.ontology_base)


def read_catalog(directory: Path | None = None) -> Catalog:
    d = directory or express_dir()
    with open(d / "schemas.toml", "rb") as fh:
        raw = tomllib.load(fh)
    return Catalog(
        directory=d,
        files=tuple(f["path"] for f in raw["file"]),
        schemas={k.lower(): v for k, v in raw.get("schema", {}).items()},
        namespace=raw["namespace"],
        ontology_base=raw["ontology_base"],
        ontology_version=raw["ontology_version"],
    )


def parse_catalog(catalog: Catalog) -> list[ParsedSchema]:
    parsed: list[ParsedSchema] = []
    for name in catalog.files:
        parsed.extend(parse_file(catalog.directory / name))
    return parsed


def load_catalog_model(directory: Path | None = None) -> tuple[Catalog, SchemaModel]:
    """Parse and resolve every schema the catalogue lists (uncached)."""
    catalog = read_catalog(directory)
    return catalog, build_model(parse_catalog(catalog), catalog.schemas)


@lru_cache(maxsize=1)
def iso14649() -> tuple[Catalog, SchemaModel]:
    """The shipped ISO 14649 model, built once per process."""
    return load_catalog_model()
