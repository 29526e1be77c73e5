"""N-Triples term syntax, written by hand for speed.

The loader produces N-Triples text and hands it to Oxigraph's bulk loader,
which parses it in Rust: measured as the fastest route into the store (going
through rdflib or pyoxigraph term objects costs several times more per triple).
"""

from __future__ import annotations

import math
from decimal import Decimal

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

#: N-Triples escapes as Oxigraph writes them (quote, backslash, the named control characters,
#: other C0 controls and DEL as \\u00XX), so that a line of this text is byte for byte the line
#: a dump of the store writes back: a replacement compares the two (store.GraphStore).
_ESCAPES = str.maketrans({**{chr(c): f"\\u{c:04X}" for c in [*range(0x20), 0x7F]},
                          "\\": "\\\\", '"': '\\"', "\n": "\\n", "\r": "\\r", "\t": "\\t",
                          "\b": "\\b", "\f": "\\f"})


def iri(value: str) -> str:
    return f"<{value}>"


def string(value: str) -> str:
    """A plain (xsd:string) literal."""
    return f'"{value.translate(_ESCAPES)}"'


def double(value: float) -> str:
    """An xsd:double literal in the form Oxigraph stores and writes it back: the shortest digits
    that read back as the value, positional, no trailing ".0" (6.0 -> "6", 1e-07 -> "0.0000001")."""
    if math.isfinite(value):
        text = repr(value)
        if "e" in text:  # rare: Python's exponent form, written out as Rust's Display does
            text = format(Decimal(text), "f")
        elif text.endswith(".0"):
            text = text[:-2]
        elif "." in text:
            text = _tie_away_from_zero(value, text)
        return f'"{text}"^^{T_DOUBLE}'
    return f'"{"NaN" if math.isnan(value) else ("INF" if value > 0 else "-INF")}"^^{T_DOUBLE}'


def _tie_away_from_zero(value: float, text: str) -> str:
    """``text`` (Python's shortest digits of ``value``) as Rust writes them: when the value lies
    exactly halfway between two shortest digit strings (562949953421312.25), Python takes the
    even last digit and Rust the one away from zero ("...312.2" against "...312.3"). In integers,
    scaled by ``2 * 10**places``: a tenth of a replicated real program's doubles are binary
    fractions such as 2.5 that reach the test, and fractions.Fraction made it most of the cost."""
    places = len(text) - text.index(".") - 1
    num, den = value.as_integer_ratio()
    scale = 2 * 10 ** places
    if scale % den:  # the exact value has more digits than a halfway point: no tie
        return text
    exact = abs(num) * (scale // den)
    shown = 2 * int(text.replace(".", "").lstrip("-"))
    if exact - shown != 1:  # a tie rounded towards zero lies 1/scale short of the exact value
        return text
    return text[:-1] + str(int(text[-1]) + 1)  # an even digit: no carry


def integer(value: int) -> str:
    return f'"{value}"^^{T_INTEGER}'


def boolean(value: bool) -> str:
    return f'"{"true" if value else "false"}"^^{T_BOOLEAN}'


def typed(lexical: str, datatype: str) -> str:
    return f'"{lexical.translate(_ESCAPES)}"^^<{datatype}>'
