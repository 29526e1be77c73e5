"""Parameter values of Part 21 instances (ISO 10303-21 12.2.2).

Plain Python types where they suffice -- ``int``, ``float``, ``str`` (decoded),
``list`` -- and small marker types for the rest, cheap enough for million-
instance files.
"""

from __future__ import annotations

from typing import Union


class Ref(int):
    """An entity instance name ``#12``."""

    __slots__ = ()

    def __repr__(self) -> str:
        return f"#{int(self)}"


class Enum(str):
    """An enumeration or logical value ``.TCP.``, stored upper-case without dots."""

    __slots__ = ()

    def __repr__(self) -> str:
        return f".{str(self)}."


class Binary(str):
    """A binary ``"0F3"``: the leading digit (unused bits) and hex digits, as written."""

    __slots__ = ()


class Typed:
    """A typed parameter ``LENGTH_MEASURE(2.5)``: type name (upper-case) and one value."""

    __slots__ = ("name", "value")

    def __init__(self, name: str, value: "Value") -> None:
        self.name = name
        self.value = value

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Typed) and (self.name, self.value) == (other.name, other.value)

    def __hash__(self) -> int:
        return hash((self.name, repr(self.value)))

    def __repr__(self) -> str:
        return f"{self.name}({self.value!r})"


class Name(str):
    """An edition-3 name that is not a plain instance reference (ISO 10303-21:2016, 12.1):
    a value instance ``@12`` (defined in the REFERENCE section, outside the file) or a
    constant ``#ORIGIN`` / ``@PI`` of the schema. Kept as written; its type is unknown here."""

    __slots__ = ()

    def __repr__(self) -> str:
        return str(self)


class _Marker:
    __slots__ = ("text",)

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text


UNSET = _Marker("$")
"""An omitted (unset OPTIONAL) value ``$``."""

DERIVED = _Marker("*")
"""A value a subtype derives, written ``*``."""

Value = Union[int, float, str, Ref, Enum, Binary, Typed, Name, _Marker, list]  # type: ignore[type-arg]
