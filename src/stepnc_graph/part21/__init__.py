"""ISO 10303-21 (Part 21) exchange structures: reader, values, diagnostics, writer.

Knows nothing of RDF or of any schema; :mod:`stepnc_graph.mapping` gives the
parsed instances their meaning.
"""

from stepnc_graph.part21.diagnostics import Diagnostic, Part21SyntaxError
from stepnc_graph.part21.reader import Header, Instance, Part21Reader, UnreadableText, read_file, read_text
from stepnc_graph.part21.values import DERIVED, UNSET, Binary, Enum, Name, Ref, Typed

__all__ = ["DERIVED", "UNSET", "Binary", "Diagnostic", "Enum", "Header", "Instance", "Name", "Part21Reader",
           "Part21SyntaxError", "Ref", "Typed", "UnreadableText", "read_file", "read_text"]
