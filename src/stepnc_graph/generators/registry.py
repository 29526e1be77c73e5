"""The generators, by name (in the manner of LinkML's generator registry): what each is built from
and where its outputs go. :func:`stepnc_graph.artefacts.build.generate` runs them all; a new
generator is one entry here."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from stepnc_graph.core.naming import Naming
from stepnc_graph.generators.context import JsonLdContextGenerator
from stepnc_graph.generators.generic import GenericVocabularyGenerator
from stepnc_graph.generators.html import HtmlReferenceGenerator
from stepnc_graph.generators.owl import OwlGenerator
from stepnc_graph.generators.p21 import P21VocabularyGenerator
from stepnc_graph.generators.pyvocab import PythonVocabularyGenerator
from stepnc_graph.generators.shacl import ShapesGenerator
from stepnc_graph.mapping.plans import Plans
from stepnc_graph.schema.catalog import Catalog
from stepnc_graph.schema.view import SchemaModel


class Generator(Protocol):
    def outputs(self) -> dict[str, str]:
        """Generated texts by path relative to the generator's directory."""
        ...


@dataclass(frozen=True)
class Inputs:
    """What the generators are built from: one resolved model and its catalogue."""

    model: SchemaModel
    catalog: Catalog
    naming: Naming
    plans: Plans
    #: the query library, whose examples the HTML reference shows (None: none)
    queries: Path | None
    #: (edition class, 2002 class) pairs the shapes' class hierarchy adds (other editions' classes)
    edition_classes: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class GeneratorEntry:
    name: str
    #: where its outputs go, relative to the project root
    directory: str
    make: Callable[[Inputs], Generator]
    description: str


GENERATORS: tuple[GeneratorEntry, ...] = (
    GeneratorEntry("owl", "ontology", lambda i: OwlGenerator(i.model, i.catalog, i.naming),
                   "the ISO 14649 classes, attribute properties and enumeration items (OWL 2)"),
    GeneratorEntry("generic", "ontology", lambda i: GenericVocabularyGenerator(i.model, i.naming),
                   "the generic attr: properties and the sga: analysis terms"),
    GeneratorEntry("p21", "ontology", lambda i: P21VocabularyGenerator(i.catalog.ontology_version),
                   "the p21: terms of the lossless mapping"),
    GeneratorEntry("context", "ontology", lambda i: JsonLdContextGenerator(i.plans, i.naming),
                   "the JSON-LD context"),
    GeneratorEntry("shacl", "shapes", lambda i: ShapesGenerator(i.model, i.catalog, i.naming, list(i.edition_classes)),
                   "the SHACL shapes of the schemas' constraints"),
    GeneratorEntry("html", "docs", lambda i: HtmlReferenceGenerator(i.model, i.catalog, i.naming, i.queries),
                   "the HTML reference of the vocabulary"),
    GeneratorEntry("pyvocab", "src/stepnc_graph", lambda i: PythonVocabularyGenerator(i.model, i.naming),
                   "the Python term namespaces"),
)


def generator(name: str) -> GeneratorEntry:
    """The generator called ``name`` (KeyError naming the known ones)."""
    for entry in GENERATORS:
        if entry.name == name:
            return entry
    raise KeyError(f"no generator {name!r}; known: {', '.join(e.name for e in GENERATORS)}")
