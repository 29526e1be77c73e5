"""What a data file's literals were before Oxigraph stored them: the names the checks
(:mod:`.engine`) and the RDF reader (:mod:`.rdfdata`) share for that record."""

from __future__ import annotations

XSD = "http://www.w3.org/2001/XMLSchema#"
#: the named graph holding what the data's literals were before Oxigraph stored them (:mod:`.rdfdata`)
LITERALS_GRAPH = "urn:stepnc-graph:validate:literals"
LITERAL = "<urn:stepnc-graph:validate#literal>"
ILL_TYPED = "<urn:stepnc-graph:validate#illTyped>"
#: integer ranges of the XSD integer types (None: unbounded)
INTEGER_RANGES: dict[str, tuple[int | None, int | None]] = {
    "integer": (None, None), "long": (-2**63, 2**63 - 1), "int": (-2**31, 2**31 - 1), "short": (-2**15, 2**15 - 1),
    "byte": (-128, 127), "nonNegativeInteger": (0, None), "positiveInteger": (1, None),
    "nonPositiveInteger": (None, 0), "negativeInteger": (None, -1), "unsignedLong": (0, 2**64 - 1),
    "unsignedInt": (0, 2**32 - 1), "unsignedShort": (0, 2**16 - 1), "unsignedByte": (0, 255),
}
#: datatypes Oxigraph stores as xsd:integer
FOLDED = frozenset(XSD + n for n in INTEGER_RANGES if n != "integer")
