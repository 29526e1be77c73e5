"""`SchemaModel`: the resolved schemas plus cached queries over them.

Modelled on LinkML's SchemaView: build once, then ask -- all attributes of an
entity, its subtypes, "is X a subtype of Y", the Part 21 attribute order, the
members of a SELECT, the base type under a defined type, where a name is
declared and in which ISO clause.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

from stepnc_graph.schema.model import (
    AggregateType,
    Attribute,
    Declaration,
    DefinedType,
    Entity,
    EnumerationType,
    NamedType,
    Redeclaration,
    SchemaInfo,
    SelectType,
    TypeRef,
)

if TYPE_CHECKING:
    import networkx as nx


@dataclass(frozen=True)
class Part21Slot:
    """One position in an entity's Part 21 record (ISO 10303-21 12.2.4).

    ``derived`` slots are written ``*`` because a subtype computes the value;
    ``type``/``optional`` are the effective ones after redeclarations.
    """

    index: int
    attribute: Attribute
    type: TypeRef
    optional: bool
    derived: bool

    @property
    def name(self) -> str:
        return self.attribute.name


class SchemaModel:
    """All schemas of one build, resolved. Names are looked up case-insensitively."""

    def __init__(self, schemas: dict[str, SchemaInfo], declarations: dict[str, Declaration]) -> None:
        self.schemas = schemas
        self.declarations = declarations
        self._p21: dict[str, tuple[Part21Slot, ...]] = {}
        self._ancestors: dict[str, tuple[str, ...]] = {}

    # -- look-ups ---------------------------------------------------------

    def get(self, name: str) -> Declaration | None:
        return self.declarations.get(name.lower())

    def __getitem__(self, name: str) -> Declaration:
        decl = self.get(name)
        if decl is None:
            raise KeyError(name)
        return decl

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name.lower() in self.declarations

    def entity(self, name: str) -> Entity:
        decl = self[name]
        if not isinstance(decl, Entity):
            raise KeyError(f"{name} is not an entity")
        return decl

    @cached_property
    def entities(self) -> dict[str, Entity]:
        return {n: d for n, d in sorted(self.declarations.items()) if isinstance(d, Entity)}

    @cached_property
    def types(self) -> dict[str, DefinedType | EnumerationType | SelectType]:
        return {n: d for n, d in sorted(self.declarations.items()) if not isinstance(d, Entity)}

    def in_schema(self, schema: str) -> list[Declaration]:
        """Declarations of one schema, in name order."""
        return [self.declarations[n] for n in sorted(self.schemas[schema.lower()].declarations)
                if n in self.declarations]

    def clause(self, name: str) -> str | None:
        """The ISO clause the catalogue gives for a declaration, if any."""
        decl = self[name]
        return self.schemas[decl.schema].clauses.get(decl.name)

    # -- scopes (ISO 10303-11 11) ---------------------------------------------

    @cached_property
    def scopes(self) -> dict[str, dict[str, str]]:
        """For each schema, visible name (alias) -> declared name.

        Computed to a fixed point because interfaces may chain and be cyclic.
        Constants, functions and rules are visible too, so interface lists that
        name them resolve.
        """
        scope: dict[str, dict[str, str]] = {}
        for s in self.schemas.values():
            own = list(s.declarations) + list(s.constants) + list(s.functions) + list(s.rules)
            scope[s.name] = {n: n for n in own}
        changed = True
        while changed:
            changed = False
            for s in self.schemas.values():
                for iface in s.interfaces:
                    source = scope.get(iface.schema)
                    if source is None:
                        continue
                    if iface.items is None:
                        pairs = list(source.items())
                    else:
                        pairs = [(alias, source[n]) for n, alias in iface.items if n in source]
                    for alias, real in pairs:
                        if alias not in scope[s.name]:
                            scope[s.name][alias] = real
                            changed = True
        return scope

    def resolve(self, name: str, schema: str) -> Declaration | None:
        """The declaration ``name`` denotes inside ``schema``, or None if not visible."""
        real = self.scopes.get(schema.lower(), {}).get(name.lower())
        return self.declarations.get(real) if real else None

    # -- entity hierarchy -------------------------------------------------

    @cached_property
    def hierarchy(self) -> nx.DiGraph:
        """Directed graph supertype -> subtype over all entities.

        networkx is imported here, not with the module: loading a program never
        needs the hierarchy graph, and networkx takes about 0.1 s to import.
        """
        import networkx as nx

        g: nx.DiGraph = nx.DiGraph()
        for e in self.entities.values():
            g.add_node(e.name)
            for st in e.supertypes:
                g.add_edge(st, e.name)
        return g

    def ancestors(self, name: str) -> tuple[str, ...]:
        """All supertypes, nearest first, each once, in SUBTYPE OF order."""
        key = name.lower()
        if key not in self._ancestors:
            out: list[str] = []
            for st in self.entity(key).supertypes:
                for n in (st, *self.ancestors(st)):
                    if n not in out:
                        out.append(n)
            self._ancestors[key] = tuple(out)
        return self._ancestors[key]

    @cached_property
    def _children(self) -> dict[str, list[str]]:
        """supertype -> direct subtypes (plain dicts: a load asks for subtypes, and networkx would
        cost it a tenth of a second of import)."""
        out: dict[str, list[str]] = {}
        for e in self.entities.values():
            for st in e.supertypes:
                out.setdefault(st, []).append(e.name)
        return out

    def subtypes(self, name: str) -> tuple[str, ...]:
        """Direct subtypes, sorted."""
        return tuple(sorted(self._children.get(name.lower(), ())))

    def all_subtypes(self, name: str) -> tuple[str, ...]:
        """Every subtype, at any depth, sorted."""
        found: set[str] = set()
        stack = list(self._children.get(name.lower(), ()))
        while stack:
            current = stack.pop()
            if current not in found:
                found.add(current)
                stack.extend(self._children.get(current, ()))
        return tuple(sorted(found))

    def is_subtype(self, name: str, of: str) -> bool:
        """True when ``name`` is ``of`` or inherits from it."""
        a, b = name.lower(), of.lower()
        return a == b or b in self.ancestors(a)


    # -- attributes -------------------------------------------------------

    def linearization(self, name: str) -> tuple[str, ...]:
        """The entity and its supertypes, supertypes first, in SUBTYPE OF order, each once.

        This is the order ISO 10303-21 12.2.4.1 lists inherited attributes in,
        and the order every attribute listing of this model follows.
        """
        out: list[str] = []

        def visit(entity: str) -> None:
            for st in self.entity(entity).supertypes:
                visit(st)
            if entity not in out:
                out.append(entity)

        visit(name.lower())
        return tuple(out)

    def all_attributes(self, name: str) -> tuple[Attribute, ...]:
        """Explicit, derived and inverse attributes, inherited ones first."""
        return tuple(a for n in self.linearization(name) for a in self.entity(n).attributes)

    def attribute(self, entity: str, name: str) -> Attribute | None:
        """The attribute ``name`` as seen from ``entity`` (own or inherited)."""
        for a in reversed(self.all_attributes(entity)):
            if a.name == name.lower():
                return a
        return None

    def redeclarations(self, name: str) -> list[tuple[Redeclaration, Attribute | None]]:
        """Redeclarations in force for ``name`` (own and inherited), nearest first."""
        out = []
        for n in (name.lower(), *self.ancestors(name)):
            for r in self.entity(n).redeclarations:
                out.append((r, self.attribute(r.supertype, r.name) if r.supertype in self else None))
        return out

    def part21_attributes(self, name: str) -> tuple[Part21Slot, ...]:
        """The explicit attributes in Part 21 record order (ISO 10303-21 12.2.4.1).

        Supertypes' attributes come first, in the order of the SUBTYPE OF list,
        each supertype expanded the same way recursively; an attribute reached
        twice through multiple inheritance appears once, at its first place.
        """
        key = name.lower()
        if key in self._p21:
            return self._p21[key]
        ordered = [a for n in self.linearization(key) for a in self.entity(n).explicit]
        overrides: dict[tuple[str, str], Redeclaration] = {}
        for r, target in self.redeclarations(key):
            if target is not None and target.key not in overrides:
                overrides[target.key] = r  # nearest redeclaration wins
        slots = []
        for i, a in enumerate(ordered):
            redeclared = overrides.get(a.key)
            slots.append(Part21Slot(
                index=i,
                attribute=a,
                type=redeclared.type if redeclared else a.type,
                optional=(redeclared.optional if redeclared and not redeclared.derived else a.optional),
                derived=bool(redeclared and redeclared.derived),
            ))
        self._p21[key] = tuple(slots)
        return self._p21[key]

    # -- types ------------------------------------------------------------

    def select_closure(self, name: str) -> tuple[str, ...]:
        """Every non-SELECT named type a SELECT admits, nested SELECTs expanded, sorted."""
        out: set[str] = set()
        stack = [name.lower()]
        seen: set[str] = set()
        while stack:
            current = stack.pop()
            if current in seen:
                continue
            seen.add(current)
            decl = self.get(current)
            target = self.select_behind(current) if decl is not None else None
            if target is not None:
                stack.extend(target.members)
            else:
                out.add(current)
        out.discard(name.lower())
        return tuple(sorted(out))

    def select_behind(self, name: str) -> SelectType | None:
        """The SELECT a name denotes, following defined-type renamings (``TYPE t = s;``)."""
        decl = self.get(name)
        seen: set[str] = set()
        while isinstance(decl, DefinedType) and isinstance(decl.underlying, NamedType) and decl.name not in seen:
            seen.add(decl.name)
            decl = self.get(decl.underlying.name)
        return decl if isinstance(decl, SelectType) else None

    def underlying_chain(self, name: str) -> tuple[list[str], TypeRef]:
        """Defined type names from ``name`` down, and the first non-defined type reached.

        E.g. ``positive_length_measure`` -> (["positive_length_measure",
        "length_measure"], SimpleType(REAL)). The last element may also be a
        NamedType of an entity, enumeration or select, or an aggregate.
        """
        chain: list[str] = []
        decl = self.get(name)
        current: TypeRef = NamedType(name.lower())
        while isinstance(decl, DefinedType) and decl.name not in chain:
            chain.append(decl.name)
            current = decl.underlying
            decl = self.get(current.name) if isinstance(current, NamedType) else None
        return chain, current

    def base_type(self, t: TypeRef) -> TypeRef:
        """``t`` with every defined type replaced by what it stands for."""
        if isinstance(t, NamedType):
            return self.underlying_chain(t.name)[1]
        return t

    def kind_of(self, name: str) -> str:
        """'entity', 'defined', 'enumeration' or 'select'."""
        decl = self[name]
        return {Entity: "entity", DefinedType: "defined", EnumerationType: "enumeration",
                SelectType: "select"}[type(decl)]

    def aggregate_depth(self, t: TypeRef) -> int:
        depth = 0
        t = self.base_type(t)
        while isinstance(t, AggregateType):
            depth += 1
            t = self.base_type(t.element)
        return depth
