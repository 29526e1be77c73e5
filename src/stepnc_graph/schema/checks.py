"""Resolution checks run once when a model is built.

Each check returns the :class:`SchemaError`s it finds, with the position of the
offending declaration, so a schema author sees every problem in one run.
"""

from __future__ import annotations

from collections.abc import Iterator

import networkx as nx

from stepnc_graph.schema.errors import SchemaError
from stepnc_graph.schema.model import (
    AggregateType,
    DefinedType,
    Entity,
    NamedType,
    SelectType,
    SourcePos,
    TypeRef,
)
from stepnc_graph.schema.view import SchemaModel


def _named(t: TypeRef) -> Iterator[str]:
    """Every type name a type reference mentions, aggregates unwrapped."""
    while isinstance(t, AggregateType):
        t = t.element
    if isinstance(t, NamedType):
        yield t.name


def check_interfaces(model: SchemaModel) -> list[SchemaError]:
    """ISO 10303-11 11.1: interfaced schemas and items must exist."""
    errors = []
    for s in model.schemas.values():
        for iface in s.interfaces:
            target = model.scopes.get(iface.schema)
            if target is None:
                errors.append(SchemaError(f"{iface.kind} FROM unknown schema {iface.schema!r}", iface.pos, s.name))
                continue
            for name, _alias in iface.items or ():
                if name not in target:
                    errors.append(SchemaError(
                        f"{iface.kind} FROM {iface.schema}: {name!r} is neither declared in nor "
                        f"interfaced into {iface.schema}", iface.pos, s.name))
    return errors


def _check_ref(model: SchemaModel, name: str, schema: str, pos: SourcePos | None, what: str) -> SchemaError | None:
    decl = model.resolve(name, schema)
    if decl is None:
        if name in model:
            return SchemaError(f"{what} {name!r} is declared in schema {model[name].schema!r} but not "
                               f"interfaced into {schema!r}", pos, schema)
        return SchemaError(f"unknown {what} {name!r}", pos, schema)
    return None


def check_references(model: SchemaModel) -> list[SchemaError]:
    """Every type named by an attribute, defined type or select is visible in its schema."""
    errors: list[SchemaError | None] = []
    for decl in model.declarations.values():
        if isinstance(decl, Entity):
            for st in decl.supertypes:
                errors.append(_check_ref(model, st, decl.schema, decl.pos, "supertype"))
            for a in decl.attributes:
                errors += [_check_ref(model, n, decl.schema, a.pos, "type") for n in _named(a.type)]
            for r in decl.redeclarations:
                errors += [_check_ref(model, n, decl.schema, r.pos, "type") for n in _named(r.type)]
        elif isinstance(decl, DefinedType):
            errors += [_check_ref(model, n, decl.schema, decl.pos, "type") for n in _named(decl.underlying)]
        elif isinstance(decl, SelectType):
            errors += [_check_ref(model, n, decl.schema, decl.pos, "select member") for n in decl.members]
    return [e for e in errors if e is not None]


def check_kinds(model: SchemaModel) -> list[SchemaError]:
    """Supertypes are entities; SUPERTYPE OF lists real subtypes; inverses and redeclarations resolve."""
    errors = []
    for e in model.entities.values():
        for st in e.supertypes:
            if st in model and not isinstance(model[st], Entity):
                errors.append(SchemaError(f"{e.name}: supertype {st!r} is not an entity", e.pos, e.schema))
        if e.supertype_expr is not None:
            for sub in e.supertype_expr.names():
                decl = model.get(sub)
                if not isinstance(decl, Entity) or e.name not in decl.supertypes:
                    errors.append(SchemaError(
                        f"{e.name}: SUPERTYPE OF names {sub!r}, which is not a direct subtype", e.pos, e.schema))
        for a in e.attributes:
            if a.inverse_of is None:
                continue
            target, forward = a.inverse_of
            if isinstance(model.get(target), Entity) and model.attribute(target, forward) is None:
                errors.append(SchemaError(f"{e.name}.{a.name}: inverse FOR {forward!r}, which {target} "
                                          f"does not have", a.pos, e.schema))
        for r in e.redeclarations:
            if r.supertype not in model or not isinstance(model[r.supertype], Entity):
                errors.append(SchemaError(f"{e.name}: redeclaration names unknown entity {r.supertype!r}",
                                          r.pos, e.schema))
            elif r.supertype not in model.ancestors(e.name) or model.attribute(r.supertype, r.name) is None:
                errors.append(SchemaError(f"{e.name}: SELF\\{r.supertype}.{r.name} does not name an "
                                          f"inherited attribute", r.pos, e.schema))
    return errors


def check_cycles(model: SchemaModel) -> list[SchemaError]:
    """No entity is its own supertype; no defined type or select contains itself."""
    errors = []
    if not nx.is_directed_acyclic_graph(model.hierarchy):
        cycle = nx.find_cycle(model.hierarchy)
        entity = model.entity(cycle[0][0])
        errors.append(SchemaError("supertype cycle: " + " -> ".join(u for u, _ in cycle) + f" -> {cycle[0][0]}",
                                  entity.pos, entity.schema))
    g: nx.DiGraph = nx.DiGraph()
    for t in model.types.values():
        if isinstance(t, DefinedType) and isinstance(t.underlying, NamedType):
            g.add_edge(t.name, t.underlying.name)
        elif isinstance(t, SelectType):
            for m in t.members:
                if not isinstance(model.get(m), Entity):
                    g.add_edge(t.name, m)
    for found in nx.simple_cycles(g):
        k = found.index(min(found))
        cycle = found[k:] + found[:k]  # start at the smallest name: stable reports
        first = model[cycle[0]]
        errors.append(SchemaError("type cycle: " + " -> ".join([*cycle, cycle[0]]), first.pos, first.schema))
    return errors


def check_model(model: SchemaModel) -> list[SchemaError]:
    errors = check_interfaces(model) + check_references(model) + check_cycles(model)
    if not errors:  # kind checks walk the hierarchy, which needs the above to hold
        errors += check_kinds(model)
    return errors
