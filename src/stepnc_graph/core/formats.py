"""The registries of formats: what a load reads, what an export writes, how query results are
laid out. Plain data, importing nothing: the CLI builds its ``--format`` choices from them without
importing a loader or an exporter, and the modules that read and write each format dispatch by
them, so a format is added in one place (and then implemented where its entry points).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import PurePath


@dataclass(frozen=True)
class InputFormat:
    """A kind of program a load reads, known by its file name's ending (any case)."""

    name: str
    suffixes: tuple[str, ...]
    #: the module that reads it (:mod:`stepnc_graph.loading.loader` dispatches by this table)
    reader: str
    description: str


@dataclass(frozen=True)
class ExportFormat:
    """A ``--format`` of ``export``: ``rdf`` names the RDF serialisation Oxigraph writes (an
    attribute of ``pyoxigraph.RdfFormat``), None for the formats written here (JSON-LD, Part 21)."""

    name: str
    description: str
    rdf: str | None = None
    #: it writes graph names (the whole store); the others write one graph's triples
    quads: bool = False
    #: it writes one graph only: the store's only program graph unless ``--graph`` names one
    one_graph: bool = False


INPUT_FORMATS: tuple[InputFormat, ...] = (
    InputFormat("part21", (".stp", ".step", ".p21"), "stepnc_graph.loading.loader", "ISO 10303-21 exchange structure"),
    InputFormat("jsonld", (".jsonld",), "stepnc_graph.loading.jsonld", "a program graph in JSON-LD"),
)

EXPORT_FORMATS: tuple[ExportFormat, ...] = (
    ExportFormat("ttl", "Turtle", rdf="TURTLE", one_graph=True),
    ExportFormat("nt", "N-Triples", rdf="N_TRIPLES", one_graph=True),
    ExportFormat("nq", "N-Quads", rdf="N_QUADS", quads=True),
    ExportFormat("trig", "TriG", rdf="TRIG", quads=True),
    ExportFormat("jsonld", "JSON-LD compacted with the shipped context"),
    ExportFormat("jsonld-tree", "JSON-LD framed as a tree (project, workplans, workingsteps, ...)"),
    ExportFormat("p21", "the graph written back as a Part 21 file", one_graph=True),
)

#: how ``query`` lays out results: the SPARQL 1.1 results formats, two for people, and RDF for
#: CONSTRUCT/DESCRIBE results
QUERY_RESULT_FORMATS: tuple[str, ...] = ("table", "csv", "tsv", "json", "md", "ttl", "nt")


def input_suffixes() -> tuple[str, ...]:
    """Every file name ending a load reads, in the order of :data:`INPUT_FORMATS`."""
    return tuple(s for f in INPUT_FORMATS for s in f.suffixes)


def input_format(path: PurePath) -> InputFormat | None:
    """The input format of a file (by its name's ending, any case), or None."""
    suffix = path.suffix.lower()
    return next((f for f in INPUT_FORMATS if suffix in f.suffixes), None)


def reads_as(path: PurePath, name: str) -> bool:
    """Whether a load reads the file ``path`` as the input format ``name``."""
    found = input_format(path)
    return found is not None and found.name == name


def export_format_names() -> tuple[str, ...]:
    return tuple(f.name for f in EXPORT_FORMATS)


def export_format(name: str) -> ExportFormat | None:
    return next((f for f in EXPORT_FORMATS if f.name == name), None)
