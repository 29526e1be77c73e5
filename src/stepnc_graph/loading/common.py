"""What every input format's loader shares (Part 21 :mod:`.loader`, JSON-LD :mod:`.jsonld`,
links :mod:`.link`): the input (:class:`Source`), the result (:class:`LoadResult`), the
provenance terms and the load's time. Below the loaders, so that none imports another for these."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.part21.diagnostics import Diagnostic

if TYPE_CHECKING:
    from stepnc_graph.mapping.editions import EditionChoice, OtherForm

DCT = "http://purl.org/dc/terms/"
OWL_SAME_AS = "<http://www.w3.org/2002/07/owl#sameAs>"
PROV = "http://www.w3.org/ns/prov#"
RDFS = "http://www.w3.org/2000/01/rdf-schema#"

class SourceError(StepncGraphError, ValueError):
    """Inputs that cannot be loaded as asked (a graph IRI twice, stdin without --base-iri, ...)."""


@dataclass(frozen=True)
class Source:
    """One input of a load: ``path`` None means standard input; ``name`` is what messages show."""

    name: str
    path: Path | None
    graph: str

    @property
    def identity(self) -> str:
        """What the graph records as its source (``dcterms:source``): the absolute path, or the name."""
        return str(self.path.resolve()) if self.path is not None else self.name


def check_iri(value: str, what: str) -> str:
    """``value`` if it is an absolute IRI; else :class:`SourceError` saying where it came from."""
    try:
        ox.NamedNode(value)
    except ValueError as e:
        raise SourceError(f"{what}: {value!r} is not an absolute IRI ({e})") from None
    return value


Progress = Callable[[int, int], None]


@dataclass
class LoadResult:
    """What one file's load did; ``instances`` counts mapped and raw instances.

    ``triples`` are the file's graph; ``derived_triples`` its derived layer
    (``<graph>/derived``, see :mod:`stepnc_graph.loading.derive`).
    """

    path: str
    graph: str
    instances: int = 0
    raw: int = 0  # kept raw: do not fit the schema, or (unreadable) do not parse
    unreadable: int = 0
    unreadable_texts: int = 0  # text that names no instance, kept (p21:unreadableText)
    triples: int = 0
    defined: int = 0
    derived_triples: int = 0
    seconds: float = 0.0
    diagnostics: list[Diagnostic] = field(default_factory=list)
    #: the Part 21 mapper wrote the graph and saw every list within its bounds (see
    #: :mod:`stepnc_graph.validation.implied`); False for a JSON-LD load
    lists_within_bounds: bool = field(default=False, repr=False)
    #: ... and saw a value for every mandatory attribute (no ``$`` or ``*`` there)
    mandatory_values_set: bool = field(default=False, repr=False)
    #: each instance's line by #id, for a load that wrote no ``p21:id``/``p21:line``
    #: triples (``positions=False``); None otherwise
    lines: dict[int, int] | None = field(default=None, repr=False)
    #: the edition of ISO 14649 the file was read in, how it was chosen and why
    #: (:func:`stepnc_graph.mapping.editions.decide_edition`); None for a JSON-LD load
    edition: EditionChoice | None = None
    #: the instances read in another edition than the file's, per entity and edition (evidence,
    #: not diagnostics: see :class:`~stepnc_graph.mapping.editions.OtherForm`)
    in_other_editions: tuple[OtherForm, ...] = ()

    @property
    def other_editions(self) -> dict[int, str]:
        """#id -> edition of each instance read in another edition than the file's."""
        return {i: f.edition for f in self.in_other_editions for i in f.ids}

    def asdict(self) -> dict[str, Any]:
        return {
            "path": self.path, "graph": self.graph,
            **({"edition": {**self.edition.asdict(), "instances_in_other_editions": [
                f.asdict() for f in self.in_other_editions]}} if self.edition else {}),
            "instances": self.instances, "raw_instances": self.raw,
            "unreadable_instances": self.unreadable, "unreadable_texts": self.unreadable_texts,
            "triples": self.triples, "derived_triples": self.derived_triples, "seconds": round(self.seconds, 3),
            "diagnostics": [{k: v for k, v in d.asdict().items() if k != "file"} for d in self.diagnostics],
        }


def load_time() -> datetime:
    """Now, or ``$SOURCE_DATE_EPOCH`` when set: the reproducible-builds convention, so that
    two loads of one file give byte-identical exports (CI, PLM diffs)."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    if epoch.isdigit():
        return datetime.fromtimestamp(int(epoch), timezone.utc)
    return datetime.now(timezone.utc)



def load_timestamp() -> str:
    """:func:`load_time` as an xsd:dateTime literal in N-Triples, written as Oxigraph writes the
    value back (UTC as ``Z``, not ``+00:00``): the text a load keeps is then the store's text
    (see stepnc_graph.store.kept_graph), and an export may read it instead of the store."""
    return f'"{load_time().strftime("%Y-%m-%dT%H:%M:%SZ")}"^^<http://www.w3.org/2001/XMLSchema#dateTime>'
