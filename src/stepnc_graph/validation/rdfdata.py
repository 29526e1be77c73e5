"""Any RDF file as the data graph of a validation: Turtle, N-Triples, N-Quads, TriG, RDF/XML.

``stepnc-graph validate DATA.ttl --shapes S.ttl --no-iso-shapes`` makes the
engine a general SHACL validator. The file is parsed by Oxigraph (its IRI the
base of relative IRIs) into one named graph of the throw-away store: every
triple of every graph of the file (a TriG or N-Quads file is validated as the
merge of its graphs, as SHACL has one data graph).

**Literals, checked while parsing.** Oxigraph stores literals by value: the
integer types derived from ``xsd:integer`` (``xsd:int``, ``xsd:byte`` ...)
are stored as ``xsd:integer``, and ``"300"^^xsd:byte`` (out of range) becomes a
valid integer. ``sh:datatype`` must see the literal as written: so each
literal of an XSD datatype is checked against its lexical space here (an
ill-typed literal is reported, and fails ``sh:datatype``), and the types of the
integer literals Oxigraph folds are noted in a side graph
(:data:`~.literals.LITERALS_GRAPH`) that the datatype checks read.
"""

from __future__ import annotations

import calendar
import re
from dataclasses import dataclass, field
from decimal import Decimal, InvalidOperation
from pathlib import Path

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.validation.literals import FOLDED, ILL_TYPED, INTEGER_RANGES, LITERAL, LITERALS_GRAPH

XSD = "http://www.w3.org/2001/XMLSchema#"
SUFFIXES = {".ttl": ox.RdfFormat.TURTLE, ".nt": ox.RdfFormat.N_TRIPLES, ".nq": ox.RdfFormat.N_QUADS,
            ".trig": ox.RdfFormat.TRIG, ".rdf": ox.RdfFormat.RDF_XML, ".owl": ox.RdfFormat.RDF_XML,
            ".jsonld": ox.RdfFormat.JSON_LD}
#: JSON-LD is a program graph (:mod:`stepnc_graph.loading.jsonld`) when the ISO 14649 shapes run, any
#: JSON-LD document otherwise; Oxigraph's parser then refuses a remote context (no network)
PROGRAM_SUFFIXES = frozenset({".jsonld"})


_TZ = r"(?:Z|[+-](?:(?:0\d|1[0-3]):[0-5]\d|14:00))?"
_DATE = r"-?(?:[1-9]\d{4,}|\d{4})-(\d{2})-(\d{2})"
_TIME = r"(?:[01]\d|2[0-3]):[0-5]\d:[0-5]\d(?:\.\d+)?|24:00:00(?:\.0+)?"
_PATTERNS = {
    "decimal": r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)",
    "double": r"[+-]?(?:(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?|INF)|NaN",
    "boolean": r"true|false|1|0",
    "date": _DATE + _TZ,
    "dateTime": _DATE + r"T(?:" + _TIME + r")" + _TZ,
    "dateTimeStamp": _DATE + r"T(?:" + _TIME + r")(?:Z|[+-](?:(?:0\d|1[0-3]):[0-5]\d|14:00))",
    "time": r"(?:" + _TIME + r")" + _TZ,
    "gYear": r"-?(?:[1-9]\d{4,}|\d{4})" + _TZ,
    "gYearMonth": r"-?(?:[1-9]\d{4,}|\d{4})-(?:0[1-9]|1[0-2])" + _TZ,
    "gMonth": r"--(?:0[1-9]|1[0-2])" + _TZ,
    "gDay": r"---(?:0[1-9]|[12]\d|3[01])" + _TZ,
    "gMonthDay": r"--(?:0[1-9]|1[0-2])-(?:0[1-9]|[12]\d|3[01])" + _TZ,
    "duration": r"-?P(?=\d|T\d)(?:\d+Y)?(?:\d+M)?(?:\d+D)?(?:T(?=\d)(?:\d+H)?(?:\d+M)?(?:\d+(?:\.\d+)?S)?)?",
    "hexBinary": r"(?:[0-9A-Fa-f]{2})*",
    "base64Binary": r"(?:[A-Za-z0-9+/]{4})*(?:[A-Za-z0-9+/]{2}==|[A-Za-z0-9+/]{3}=)?",
}
_PATTERNS["float"] = _PATTERNS["double"]
_COMPILED = {XSD + k: re.compile(v) for k, v in _PATTERNS.items()}
_INTEGER = re.compile(r"[+-]?\d+")


def well_typed(lexical: str, datatype: str) -> bool:
    """Whether ``lexical`` is in the lexical space of the XSD ``datatype`` (other datatypes: True)."""
    if datatype.startswith(XSD) and datatype[len(XSD):] in INTEGER_RANGES:
        if not _INTEGER.fullmatch(lexical):
            return False
        low, high = INTEGER_RANGES[datatype[len(XSD):]]
        value = int(lexical)
        return (low is None or value >= low) and (high is None or value <= high)
    pattern = _COMPILED.get(datatype)
    if pattern is None:
        return True
    m = pattern.fullmatch(lexical)
    if m is None:
        return False
    if datatype in (XSD + "date", XSD + "dateTime", XSD + "dateTimeStamp"):
        return _real_day(lexical)
    if datatype == XSD + "decimal":
        try:
            Decimal(lexical)
        except InvalidOperation:
            return False
    return True


def _real_day(lexical: str) -> bool:
    m = re.match(r"(-?\d+)-(\d{2})-(\d{2})", lexical)
    if m is None:
        return False
    year, month, day = int(m.group(1)), int(m.group(2)), int(m.group(3))
    if not 1 <= month <= 12:
        return False
    leap = calendar.isleap(year if year > 0 else year + 1) if year != 0 else True
    days = [31, 29 if leap else 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31][month - 1]
    return 1 <= day <= days


class DataError(StepncGraphError, ValueError):
    """An RDF data file that cannot be read (its position in the message)."""


@dataclass
class IllTyped:
    """A literal outside its datatype's lexical space, and the triple holding it (N-Triples terms)."""

    subject: str
    predicate: str
    literal: str


@dataclass
class RdfLoad:
    """What :func:`load_rdf` wrote: the graph, its triple count, the ill-typed literals found."""

    path: Path
    graph: str
    triples: int = 0
    ill_typed: list[IllTyped] = field(default_factory=list)


def rdf_format(path: Path, programs: bool = False) -> ox.RdfFormat | None:
    """The RDF format of a data file by its suffix; None when it is no RDF file validate reads this
    way (``programs``: a ``.jsonld`` file is a program graph, read by the loader)."""
    if programs and path.suffix.lower() in PROGRAM_SUFFIXES:
        return None
    return SUFFIXES.get(path.suffix.lower())


def load_rdf(store: ox.Store, path: Path, graph: str) -> RdfLoad:
    """Parse ``path`` into the named graph ``graph`` of ``store`` (every graph of the file merged),
    checking its literals (module docstring). Raises :class:`DataError` for a file that does not parse."""
    fmt = rdf_format(path)
    if fmt is None:
        raise DataError(f"{path}: not an RDF file this command reads ({', '.join(sorted(SUFFIXES))})")
    target = ox.NamedNode(graph)
    result = RdfLoad(path, graph)
    side: list[ox.Quad] = []
    integers: list[ox.Literal] = []
    folded = False
    try:
        quads = ox.parse(path=str(path), format=fmt, base_iri=path.resolve().as_uri())
        batch: list[ox.Quad] = []
        for q in quads:
            batch.append(ox.Quad(q.subject, q.predicate, q.object, target))
            o = q.object
            if isinstance(o, ox.Literal) and o.datatype.value.startswith(XSD):
                dt = o.datatype.value
                if not well_typed(o.value, dt):
                    result.ill_typed.append(IllTyped(str(q.subject), str(q.predicate), str(o)))
                    side.append(ox.Quad(o.datatype, ox.NamedNode(ILL_TYPED[1:-1]), o, ox.NamedNode(LITERALS_GRAPH)))
                if dt in FOLDED:
                    folded = True
                    side.append(ox.Quad(o.datatype, ox.NamedNode(LITERAL[1:-1]), o, ox.NamedNode(LITERALS_GRAPH)))
                elif dt == XSD + "integer":
                    integers.append(o)
            if len(batch) >= 100_000:
                store.extend(batch)
                result.triples += len(batch)
                batch = []
        store.extend(batch)
        result.triples += len(batch)
    except (SyntaxError, OSError) as exc:
        raise DataError(f"{path}: {exc}") from None
    if folded:  # an xsd:integer stored like an xsd:int: say which one it was
        side += [ox.Quad(i.datatype, ox.NamedNode(LITERAL[1:-1]), i, ox.NamedNode(LITERALS_GRAPH)) for i in integers]
    if side:
        store.extend(side)
    return result


