"""Compiled mapping plans: for each entity, how each Part 21 parameter becomes RDF.

Built once per model from :mod:`stepnc_graph.vocabulary.typemap` decisions, so the hot
loop of the loader only looks things up. The writer uses the same plans in
reverse, which keeps load and export consistent by construction.

The shipped model's plans are compiled by ``stepnc-graph ontology build`` into
the compiled-model file (:mod:`stepnc_graph.schema.cache`): :meth:`Plans.dump`
writes them, :meth:`Plans.restore` reads them back without recomputing.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

from stepnc_graph.core.naming import P21_NS, Naming
from stepnc_graph.schema.model import (
    AggregateType,
    BaseType,
    DefinedType,
    Entity,
    EnumerationType,
    GenericType,
    NamedType,
    SelectType,
    SimpleType,
    TypeRef,
)
from stepnc_graph.schema.view import SchemaModel


@dataclass(frozen=True)
class Encoding:
    """How values of one type are read from Part 21 and written as RDF terms.

    ``kind``: integer, real, string, boolean, logical, binary, entity, enum,
    select, list, any. ``items`` maps enumeration items (upper-case) to IRIs;
    ``typed`` maps a select's defined-type names (upper-case) to (class IRI,
    encoding of its underlying type); ``element`` is the member encoding of a list.
    """

    kind: str
    label: str
    items: dict[str, str] = field(default_factory=dict, compare=False)
    typed: dict[str, tuple[str, "Encoding"]] = field(default_factory=dict, compare=False)
    accepts_refs: bool = False
    element: "Encoding | None" = None
    datatype: str | None = None
    lower: int | None = 0  # bounds of a list (None: an expression bound); upper None is '?'
    upper: int | None = None


@dataclass(frozen=True)
class Slot:
    """One Part 21 parameter position of an entity record."""

    index: int
    name: str
    entity: str
    prop: str  # the property IRI, bare
    encoding: Encoding
    optional: bool
    derived: bool
    repeated: bool  # a top-level SET: one triple per member


@dataclass(frozen=True)
class EntityPlan:
    name: str
    cls: str  # class IRI, bare
    abstract: bool
    slots: tuple[Slot, ...]
    own_slots: tuple[Slot, ...]  # the entity's own explicit attributes (complex instances)
    #: positions in ``slots`` / ``own_slots`` of a string attribute named ``its_id``
    #: (the label ISO 14649-10 gives projects, workpieces, executables, features,
    #: operations, ...), used to mint alias IRIs for PLM links; None without one.
    its_id: int | None = None
    own_its_id: int | None = None


def unread_properties(plans: "Plans", reads: frozenset[str]) -> frozenset[str]:
    """The attribute properties (bare IRIs) of ``plans`` that are not in ``reads`` and whose values
    are never typed nodes (a SELECT's typed value is a node of its own class: any check targeting
    that class reads it), so that a reader of ``reads`` alone does not miss their lines."""
    def types_nodes(enc: Encoding | None) -> bool:
        return enc is not None and ((enc.kind == "select" and bool(enc.typed))
                                    or (enc.kind == "list" and types_nodes(enc.element)))

    return frozenset(slot.prop for plan in plans.entities.values() for slot in (*plan.slots, *plan.own_slots)
                     if slot.prop not in reads and not types_nodes(slot.encoding))


class Plans:
    """Plans for every entity of a model, keyed by upper-case Part 21 name."""

    def __init__(self, model: SchemaModel, naming: Naming) -> None:
        self.model = model
        self.n = naming
        self._enc: dict[str, Encoding] = {}
        self.entities: dict[str, EntityPlan] = {}
        for e in model.entities.values():
            self.entities[e.name.upper()] = self._entity_plan(e)
        self._index()

    def _index(self) -> None:
        """The look-up tables derived from ``entities`` and ``_enc``."""
        self.by_class = {p.cls: p for p in self.entities.values()}
        # Reverse maps for the writer. Every enumeration and SELECT encoding is
        # cached in _enc by now (plans of all entities were built above).
        self.item_names = {iri: item for enc in self._enc.values() for item, iri in enc.items.items()}
        self.typed_names = {cls: name for enc in self._enc.values() for name, (cls, _) in enc.typed.items()}

    # -- compiled form --------------------------------------------------------

    def dump(self) -> dict[str, list[Any]]:
        """The plans as JSON values: an encoding table and one record per entity.

        Encodings are listed once each, nested ones before the encodings that
        use them, and referred to by position; IRIs in this vocabulary's
        namespace are written without it.
        """
        table: list[Any] = []
        index: dict[int, int] = {}
        local = self._local

        def encoding(e: Encoding) -> int:
            if id(e) not in index:
                element = None if e.element is None else encoding(e.element)
                typed = {name: [local(cls), encoding(inner)] for name, (cls, inner) in e.typed.items()}
                items = {item: local(iri) for item, iri in e.items.items()}
                index[id(e)] = len(table)
                table.append([e.kind, e.label, items, typed, e.accepts_refs, element, e.datatype, e.lower, e.upper])
            return index[id(e)]

        def slot(s: Slot) -> list[Any]:
            return [s.index, s.name, s.entity, local(s.prop), encoding(s.encoding), s.optional, s.derived,
                    s.repeated]

        named = [[name, encoding(e)] for name, e in self._enc.items()]
        entities = [[p.name, local(p.cls), p.abstract, [slot(s) for s in p.slots], [slot(s) for s in p.own_slots],
                     p.its_id, p.own_its_id] for p in self.entities.values()]
        return {"encodings": table, "named": named, "entities": entities}

    def _local(self, iri: str) -> str:
        name = self.n.local_name(iri)
        if name is None:
            raise ValueError(f"{iri} is not in the vocabulary namespace {self.n.namespace}")
        return name

    @classmethod
    def restore(cls, model: SchemaModel, naming: Naming, data: dict[str, list[Any]]) -> "Plans":
        """Plans equal to ``Plans(model, naming)`` from what :meth:`dump` wrote for them."""
        ns = naming.namespace
        table: list[Encoding] = []
        for kind, label, items, typed, refs, element, datatype, lower, upper in data["encodings"]:
            table.append(Encoding(kind, label, {k: ns + v for k, v in items.items()},
                                  {k: (ns + c, table[i]) for k, (c, i) in typed.items()}, refs,
                                  None if element is None else table[element], datatype, lower, upper))

        def slots(records: list[list[Any]]) -> tuple[Slot, ...]:
            return tuple(Slot(i, name, entity, ns + prop, table[e], optional, derived, repeated)
                         for i, name, entity, prop, e, optional, derived, repeated in records)

        plans = cls.__new__(cls)
        plans.model = model
        plans.n = naming
        plans._enc = {name: table[i] for name, i in data["named"]}
        plans.entities = {name.upper(): EntityPlan(name, ns + c, abstract, slots(all_slots), slots(own), its_id,
                                                   own_its_id)
                          for name, c, abstract, all_slots, own, its_id, own_its_id in data["entities"]}
        plans._index()
        return plans

    # -- encodings ----------------------------------------------------------

    def encoding(self, t: TypeRef) -> Encoding:
        if isinstance(t, NamedType):
            if t.name not in self._enc:
                self._enc[t.name] = self._named(t.name)
            return self._enc[t.name]
        if isinstance(t, SimpleType):
            return self._simple(t.base)
        if isinstance(t, AggregateType):
            element = self.encoding(t.element)
            return Encoding("list", str(t), element=element, lower=t.lower, upper=t.upper)
        assert isinstance(t, GenericType)
        return Encoding("any", str(t))

    def _simple(self, base: BaseType, label: str | None = None) -> Encoding:
        kind = {BaseType.INTEGER: "integer", BaseType.REAL: "real", BaseType.NUMBER: "real",
                BaseType.STRING: "string", BaseType.BOOLEAN: "boolean", BaseType.LOGICAL: "logical",
                BaseType.BINARY: "binary"}[base]
        from stepnc_graph.vocabulary.typemap import XSD_OF  # rdflib: only when plans are built, not restored

        return Encoding(kind, label or base.value, datatype=str(XSD_OF[base]))

    def _named(self, name: str) -> Encoding:
        decl = self.model[name]
        if isinstance(decl, Entity):
            return Encoding("entity", name, accepts_refs=True)
        if isinstance(decl, EnumerationType):
            return Encoding("enum", name, items={i.upper(): str(self.n.enum_item(name, i)) for i in decl.items})
        select = self.model.select_behind(name)
        if select is not None:
            return self._select(name, select)
        assert isinstance(decl, DefinedType)
        inner = self.encoding(decl.underlying)
        return dataclasses.replace(inner, label=name)

    def _select(self, name: str, select: SelectType) -> Encoding:
        items: dict[str, str] = {}
        typed: dict[str, tuple[str, Encoding]] = {}
        refs = False
        for member in self.model.select_closure(select.name):
            decl = self.model[member]
            if isinstance(decl, Entity):
                refs = True
            elif isinstance(decl, EnumerationType):
                for item in decl.items:
                    items.setdefault(item.upper(), str(self.n.enum_item(member, item)))
            elif isinstance(decl, DefinedType):
                typed[member.upper()] = (str(self.n.declaration(member)), self.encoding(decl.underlying))
        return Encoding("select", name, items=items, typed=typed, accepts_refs=refs)

    # -- entities -----------------------------------------------------------

    def _slot(self, s_index: int, attr_entity: str, attr_name: str, t: TypeRef, optional: bool,
              derived: bool) -> Slot:
        base = self.model.base_type(t)
        repeated = isinstance(base, AggregateType) and base.kind == "SET"
        encoding = self.encoding(base.element if repeated else t)  # type: ignore[union-attr]
        return Slot(s_index, attr_name, attr_entity, str(self.n.attribute(attr_entity, attr_name)), encoding,
                    optional, derived, repeated)

    def _entity_plan(self, e: Entity) -> EntityPlan:
        slots = tuple(self._slot(s.index, s.attribute.entity, s.name, s.type, s.optional, s.derived)
                      for s in self.model.part21_attributes(e.name))
        own = tuple(self._slot(i, e.name, a.name, a.type, a.optional, False) for i, a in enumerate(e.explicit))
        return EntityPlan(e.name, str(self.n.declaration(e.name)), e.abstract, slots, own,
                          _label_index(slots), _label_index(own))


LABEL_ATTRIBUTE = "its_id"


def _label_index(slots: tuple[Slot, ...]) -> int | None:
    """The position of the ``its_id`` string attribute among ``slots``, if any."""
    for position, slot in enumerate(slots):
        if slot.name.lower() == LABEL_ATTRIBUTE and slot.encoding.kind == "string" and not slot.repeated:
            return position
    return None


P21_ID = f"<{P21_NS}id>"
P21_LINE = f"<{P21_NS}line>"
P21_SECTION = f"<{P21_NS}dataSection>"
P21_DERIVED = f"<{P21_NS}derivedValue>"
P21_EMPTY = f"<{P21_NS}emptyAggregate>"
P21_VALUE = f"<{P21_NS}value>"
P21_RAW = f"<{P21_NS}RawInstance>"
P21_RAW_TEXT = f"<{P21_NS}rawText>"
P21_ENTITY_NAME = f"<{P21_NS}entityName>"
#: on an instance read in another edition than its file's (see mapping.editions), and on the file's graph
P21_EDITION = f"<{P21_NS}edition>"
P21_UNREADABLE = f"<{P21_NS}UnreadableInstance>"
P21_SYNTAX_ERROR = f"<{P21_NS}syntaxError>"
P21_REPAIRED_TEXT = f"<{P21_NS}repairedText>"
P21_DUPLICATE = f"<{P21_NS}duplicateDefinition>"
P21_UNREADABLE_TEXT = f"<{P21_NS}unreadableText>"
P21_UNSET = f"<{P21_NS}unset>"
P21_UNKNOWN = f"{P21_NS}logicalUnknown"


@lru_cache(maxsize=4)
def plans_for(model: SchemaModel, naming: Naming) -> Plans:
    return Plans(model, naming)


@lru_cache(maxsize=1)
def iso14649_plans() -> Plans:
    """The plans of the shipped ISO 14649 model, once per process.

    Read from the compiled-model file; built from the model when that file was
    missing or stale (:func:`stepnc_graph.schema.cache.shipped` warned then).
    """
    from stepnc_graph.schema.cache import shipped

    compiled = shipped()
    naming = compiled.catalog.naming
    if compiled.plans is None:
        return plans_for(compiled.model, naming)
    return Plans.restore(compiled.model, naming, compiled.plans)
