"""N-Triples term syntax, written by hand for speed.

The loader produces N-Triples text and hands it to Oxigraph's bulk loader,
which parses it in Rust: measured as the fastest route into the store (going
through rdflib or pyoxigraph term objects costs several times more per triple).
"""

from __future__ import annotations

import math

XSD = "http://www.w3.org/2001/XMLSchema#"
RDF = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"

T_DOUBLE = f"<{XSD}double>"
T_INTEGER = f"<{XSD}integer>"
T_BOOLEAN = f"<{XSD}boolean>"
T_HEX = f"<{XSD}hexBinary>"
RDF_TYPE = f"<{RDF}type>"
RDF_FIRST = f"<{RDF}first>"
RDF_REST = f"<{RDF}rest>"
RDF_NIL = f"<{RDF}nil>"
RDFS_LABEL = "<http://www.w3.org/2000/01/rdf-schema#label>"

_ESCAPES = str.maketrans({"\\": "\\\\", '"': '\\"', "\n": "\\n", "\r": "\\r"})


def iri(value: str) -> str:
    return f"<{value}>"


def string(value: str) -> str:
    """A plain (xsd:string) literal."""
    return f'"{value.translate(_ESCAPES)}"'


def double(value: float) -> str:
    if math.isfinite(value):
        return f'"{value!r}"^^{T_DOUBLE}'
    return f'"{"NaN" if math.isnan(value) else ("INF" if value > 0 else "-INF")}"^^{T_DOUBLE}'


def integer(value: int) -> str:
    return f'"{value}"^^{T_INTEGER}'


def boolean(value: bool) -> str:
    return f'"{"true" if value else "false"}"^^{T_BOOLEAN}'


def typed(lexical: str, datatype: str) -> str:
    return f'"{lexical.translate(_ESCAPES)}"^^<{datatype}>'
