"""EXPRESS (ISO 10303-11) front end: source text to syntax trees with positions.

This layer knows nothing about RDF; the schema model (`stepnc_graph.schema`)
is built from what it returns.
"""

from stepnc_graph.express.errors import ExpressSyntaxError
from stepnc_graph.express.parser import ParsedSchema, parse_file, parse_text

__all__ = ["ExpressSyntaxError", "ParsedSchema", "parse_file", "parse_text"]
