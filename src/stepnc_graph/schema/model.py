"""The resolved schema model: the contract every other part of stepnc-graph uses.

Built from EXPRESS syntax trees by :mod:`stepnc_graph.schema.builder`. All
names are stored lower-case because EXPRESS names are case-insensitive
(ISO 10303-11 7.1.2); look-ups lower-case their argument. Every declaration
knows its schema and its source position.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any, Literal, Union


@dataclass(frozen=True)
class SourcePos:
    """1-based position of a declaration in an EXPRESS file."""

    file: str
    line: int
    column: int

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"


class BaseType(enum.Enum):
    """The EXPRESS simple data types (ISO 10303-11 8.1)."""

    NUMBER = "NUMBER"
    REAL = "REAL"
    INTEGER = "INTEGER"
    LOGICAL = "LOGICAL"
    BOOLEAN = "BOOLEAN"
    STRING = "STRING"
    BINARY = "BINARY"


@dataclass(frozen=True)
class SimpleType:
    base: BaseType
    width: int | None = None
    fixed: bool = False

    def __str__(self) -> str:
        if self.width is None:
            return self.base.value
        return f"{self.base.value}({self.width}){' FIXED' if self.fixed else ''}"


@dataclass(frozen=True)
class NamedType:
    """A reference to an entity or a defined/enumeration/select type, by name."""

    name: str

    def __str__(self) -> str:
        return self.name


AggregateKind = Literal["LIST", "SET", "BAG", "ARRAY"]


@dataclass(frozen=True)
class AggregateType:
    """LIST/SET/BAG/ARRAY with bounds; ``upper`` None means ``?`` (unbounded).

    ``lower``/``upper`` are None where the bound is an expression that is not a
    literal integer (kept as text in ``bound_text``).
    """

    kind: AggregateKind
    element: "TypeRef"
    lower: int | None = 0
    upper: int | None = None
    unique: bool = False
    optional_elements: bool = False
    bound_text: str | None = None

    def __str__(self) -> str:
        if self.bound_text is not None:
            bounds = f" [{self.bound_text}]"
        elif self.kind == "LIST" and self.lower == 0 and self.upper is None:
            bounds = ""
        else:
            bounds = f" [{self.lower}:{'?' if self.upper is None else self.upper}]"
        flags = (" OPTIONAL" if self.optional_elements else "") + (" UNIQUE" if self.unique else "")
        return f"{self.kind}{bounds} OF{flags} {self.element}"


@dataclass(frozen=True)
class GenericType:
    """GENERIC / GENERIC_ENTITY / AGGREGATE: only legal in algorithm parameters."""

    label: str | None = None

    def __str__(self) -> str:
        return "GENERIC" + (f":{self.label}" if self.label else "")


TypeRef = Union[SimpleType, NamedType, AggregateType, GenericType]


# -- supertype expressions (ISO 10303-11 9.2.5) -------------------------------


@dataclass(frozen=True)
class SupertypeExpr:
    """``ONEOF(...)``, ``AND`` or ``ANDOR`` over subtype names and sub-expressions."""

    op: Literal["ONEOF", "AND", "ANDOR"]
    operands: tuple["SupertypeOperand", ...]

    def names(self) -> list[str]:
        out: list[str] = []
        for operand in self.operands:
            out.extend(operand.names() if isinstance(operand, SupertypeExpr) else [operand])
        return out

    def __str__(self) -> str:
        if self.op == "ONEOF":
            return "ONEOF(" + ", ".join(map(str, self.operands)) + ")"
        return "(" + f" {self.op} ".join(map(str, self.operands)) + ")"


SupertypeOperand = Union[str, SupertypeExpr]


# -- rules ---------------------------------------------------------------------


@dataclass(frozen=True)
class WhereRule:
    """A domain rule: its label, its expression's source text and parsed tree."""

    label: str
    source: str
    expr: Any = field(compare=False, repr=False)
    pos: SourcePos | None = field(default=None, compare=False)


@dataclass(frozen=True)
class UniqueRule:
    label: str
    attributes: tuple[str, ...]


# -- declarations -----------------------------------------------------------


AttributeKind = Literal["explicit", "derived", "inverse"]


@dataclass(frozen=True)
class Attribute:
    """An attribute declared (not redeclared) by ``entity``.

    For inverse attributes ``inverse_of`` names the forward attribute
    ``(entity, attribute)`` and ``type`` is the aggregate (or named) type.
    For derived ones ``expression`` is the source text.
    """

    name: str
    entity: str
    type: TypeRef
    kind: AttributeKind = "explicit"
    optional: bool = False
    expression: str | None = None
    inverse_of: tuple[str, str] | None = None
    pos: SourcePos | None = field(default=None, compare=False)

    @property
    def key(self) -> tuple[str, str]:
        return (self.entity, self.name)


@dataclass(frozen=True)
class Redeclaration:
    """``SELF\\supertype.attr`` re-declared in ``entity`` (ISO 10303-11 9.2.3.4).

    ``derived`` means the subtype computes the value, so Part 21 writes ``*``.
    """

    entity: str
    supertype: str
    name: str
    type: TypeRef
    optional: bool
    derived: bool
    renamed_to: str | None = None
    pos: SourcePos | None = field(default=None, compare=False)


@dataclass
class Entity:
    name: str
    schema: str
    supertypes: tuple[str, ...] = ()
    abstract: bool = False
    supertype_expr: SupertypeExpr | None = None
    attributes: tuple[Attribute, ...] = ()
    redeclarations: tuple[Redeclaration, ...] = ()
    unique_rules: tuple[UniqueRule, ...] = ()
    where_rules: tuple[WhereRule, ...] = ()
    pos: SourcePos | None = None

    @property
    def explicit(self) -> tuple[Attribute, ...]:
        return tuple(a for a in self.attributes if a.kind == "explicit")


@dataclass
class DefinedType:
    """``TYPE name = underlying;`` where underlying is a simple, named or aggregate type."""

    name: str
    schema: str
    underlying: TypeRef
    where_rules: tuple[WhereRule, ...] = ()
    pos: SourcePos | None = None


@dataclass
class EnumerationType:
    name: str
    schema: str
    items: tuple[str, ...]
    extensible: bool = False
    based_on: str | None = None
    where_rules: tuple[WhereRule, ...] = ()
    pos: SourcePos | None = None


@dataclass
class SelectType:
    name: str
    schema: str
    members: tuple[str, ...]
    extensible: bool = False
    based_on: str | None = None
    where_rules: tuple[WhereRule, ...] = ()
    pos: SourcePos | None = None


TypeDecl = Union[DefinedType, EnumerationType, SelectType]
Declaration = Union[Entity, DefinedType, EnumerationType, SelectType]


@dataclass(frozen=True)
class Interface:
    """A REFERENCE FROM / USE FROM clause; ``items`` None imports the whole schema.

    Each item is ``(name, alias)``; alias equals name when there is no ``AS``.
    """

    kind: Literal["REFERENCE", "USE"]
    schema: str
    items: tuple[tuple[str, str], ...] | None
    pos: SourcePos | None = field(default=None, compare=False)


@dataclass
class SchemaInfo:
    """One EXPRESS schema, with what the project catalogue says of its origin."""

    name: str
    file: str
    interfaces: tuple[Interface, ...] = ()
    declarations: tuple[str, ...] = ()
    constants: tuple[str, ...] = ()
    functions: tuple[str, ...] = ()
    rules: tuple[str, ...] = ()
    iso_part: str | None = None
    title: str | None = None
    edition: str | None = None
    version: str | None = None
    status: str | None = None
    source: str | None = None
    clauses: dict[str, str] = field(default_factory=dict)
