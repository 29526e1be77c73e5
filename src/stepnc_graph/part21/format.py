"""Writing parsed Part 21 values and instances back as Part 21 text.

Used where an instance must be written from its parsed form rather than its
source text: a raw instance the lenient reader repaired (its source text is
not valid Part 21, its parsed form is). The RDF writer shares
:func:`format_real` so both write REALs alike.
"""

from __future__ import annotations

import math
from typing import Any

from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.part21.reader import Header, Instance
from stepnc_graph.part21.strings import encode
from stepnc_graph.part21.values import DERIVED, UNSET, Binary, Enum, Name, Ref, Typed


class FormatError(StepncGraphError, ValueError):
    """A value that Part 21 cannot write (infinity, NaN)."""


def format_real(value: float) -> str:
    """A Part 21 REAL: always with a decimal point (``1.``, ``2.5E-03``)."""
    text = repr(float(value))
    if text in ("inf", "-inf", "nan"):
        raise FormatError(f"{text} cannot be written in Part 21")
    if "e" in text:
        mantissa, exponent = text.split("e")
        return (mantissa if "." in mantissa else mantissa + ".") + "E" + exponent
    return text


def _read_real(value: float) -> str:
    """A REAL as the reader read it: one beyond a double's range was read as infinity and is
    written as a REAL beyond it again, which reads back the same (``1.E999``)."""
    if math.isinf(value):
        return "1.E999" if value > 0 else "-1.E999"
    return format_real(value)


def format_value(value: Any) -> str:
    """The Part 21 text of one parameter value the reader parsed."""
    if value is UNSET:
        return "$"
    if value is DERIVED:
        return "*"
    kind = type(value)
    if kind is Ref:
        return f"#{int(value)}"
    if kind is Enum:
        return f".{value}."
    if kind is Binary:
        return f'"{value}"'
    if kind is Name:
        return str(value)
    if kind is Typed:
        return f"{value.name}({format_value(value.value)})"
    if kind is list:
        return "(" + ",".join(format_value(v) for v in value) + ")"
    if kind is int:
        return str(value)
    if kind is float:
        return _read_real(value)
    if kind is str:
        return encode(value)
    raise FormatError(f"unexpected value {value!r}")


def format_instance(inst: Instance) -> str:
    """``#id=NAME(params);`` or ``#id=(A(..)B(..));`` from the parsed instance."""
    if inst.parts is None:
        return f"#{inst.id}={inst.name}({','.join(format_value(v) for v in inst.params)});"
    parts = "".join(f"{name}({','.join(format_value(v) for v in params)})" for name, params in inst.parts)
    return f"#{inst.id}=({parts});"


def format_header(header: Header) -> str:
    """The HEADER section from its parsed entities (``HEADER;`` to ``ENDSEC;``)."""
    entities = "".join(f"{name}({','.join(format_value(v) for v in params)});\n"
                       for name, params in header.entities.items())
    return f"HEADER;\n{entities}ENDSEC;"
