"""A catalogue of EXPRESS schemas (``ontology/express/schemas.toml``) and the model built from it.

The EXPRESS parser and the builder are imported only when a model is built from the EXPRESS;
the shipped model is read from its compiled form (:mod:`stepnc_graph.schema.catalog`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from stepnc_graph.core.resources import express_dir

if TYPE_CHECKING:
    from stepnc_graph.express.parser import ParsedSchema
    from stepnc_graph.core.naming import Naming
    from stepnc_graph.schema.view import SchemaModel


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
        from stepnc_graph.core.naming import Naming

        return Naming(self.namespace, self.ontology_base)


def read_catalog(directory: Path | None = None) -> Catalog:
    import tomllib

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
    from stepnc_graph.express.parser import parse_file

    parsed: list[ParsedSchema] = []
    for name in catalog.files:
        parsed.extend(parse_file(catalog.directory / name))
    return parsed


def load_catalog_model(directory: Path | None = None) -> tuple[Catalog, SchemaModel]:
    """Parse and resolve every schema the catalogue lists (uncached)."""
    from stepnc_graph.schema.builder import build_model

    catalog = read_catalog(directory)
    return catalog, build_model(parse_catalog(catalog), catalog.schemas)


#: Editions other than the shipped one, each a catalogue of its own under ``ontology/editions/``.
EDITIONS = ("fdis2001",)


def edition_directory(edition: str) -> Path:
    """The directory of an edition's catalogue (``schemas.toml`` and its EXPRESS files)."""
    if edition not in EDITIONS:
        raise KeyError(f"unknown edition {edition!r}; known: {', '.join(EDITIONS)}")
    return express_dir().parent / "editions" / edition


def load_edition_model(edition: str, directory: Path | None = None) -> tuple[Catalog, SchemaModel]:
    """Parse and resolve the schemas of another edition (uncached), e.g. ``fdis2001``: the
    ISO/FDIS 14649-10 and -11 of 2001. ``directory`` overrides where its catalogue is."""
    return load_catalog_model(directory or edition_directory(edition))
