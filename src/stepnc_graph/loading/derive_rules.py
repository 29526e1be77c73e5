"""The rules of the derived layer (:mod:`.derive`), compiled from the schemas once per edition:
which classes get their closure, which attributes their generic values and labels, which lists
their positions; the tables the mapper writes the streamed part of the layer from."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.mapping.editions import SHIPPED, check_edition, edition_terms
from stepnc_graph.mapping.mapper import DerivedTables
from stepnc_graph.mapping.ntriples import RDFS_LABEL
from stepnc_graph.core.naming import (
    ANALYSIS_NS,
    P21_NS,
    Naming,
    generic_attribute_iri,
)
from stepnc_graph.schema.model import AggregateType, TypeRef
from stepnc_graph.schema.view import SchemaModel
from stepnc_graph.vocabulary.analysis import ANALYSIS_CLASSES, derived_entities

if TYPE_CHECKING:
    from stepnc_graph.store import Store


RDF_NS = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
RDF_TYPE = f"<{RDF_NS}type>"
RDF_FIRST = ox.NamedNode(RDF_NS + "first")
RDF_REST = ox.NamedNode(RDF_NS + "rest")
XSD_INTEGER = "http://www.w3.org/2001/XMLSchema#integer"
#: the layer's format: what the library queries expect to find (``sga:layerVersion`` on the layer).
#: 2: steps carry their program, workingstep #id, operation #id and class; class counts
#: 3: steps carry their operation, the names of their workingstep, operation, workplan, setup and tool,
#:    the tool's #id and its body's class; features their #id, class and program
#: 4: steps carry the local names of their operation's and tool body's classes; features and
#:    operations the local names of their own classes (sga:typeName)
LAYER_VERSION = 4
#: characters of layer text per bulk-load call: the store's own batch (see store.tuning.BATCH_CHARS)
TEXT_PIECE = 12_000_000

def sga(name: str) -> str:
    return f"<{ANALYSIS_NS}{name}>"


def integer_literal(n: int) -> str:
    return f'"{n}"^^<{XSD_INTEGER}>'


@dataclass(frozen=True)
class DeriveRules:
    """The model-dependent part of the derivation, compiled once per process.

    ``construct`` is the CONSTRUCT of closure, generic values and labels
    (``blank_values`` selects the generic values that are blank nodes);
    ``list_properties`` the ISO 14649 attributes whose values are
    ``rdf:List`` s; ``workingsteps`` / ``structures`` the classes of
    executables the order walk tells apart.
    """

    construct: str
    blank_values: str
    list_properties: tuple[str, ...]
    workingsteps: frozenset[str]
    structures: frozenset[str]
    operation_properties: tuple[str, ...]
    tool_properties: tuple[str, ...]
    executables: tuple[str, ...]
    superclasses: dict[str, tuple[str, ...]] = field(compare=False)
    generic: dict[str, str] = field(compare=False)
    labels: frozenset[str] = field(compare=False, default=frozenset())

    def tables(self) -> DerivedTables:
        """The part of the layer the loader's mapper writes as it maps (closure, generic values, labels)."""
        return DerivedTables(self.superclasses, self.generic, self.labels, frozenset(self.list_properties),
                             ANALYSIS_NS + "index")


def _is_a(model: SchemaModel) -> dict[str, set[str]]:
    """class -> its direct superclasses: EXPRESS supertypes and the analysis classes.

    SELECTs are left out: the vocabulary makes their members subclasses (so
    ``rdfs:subClassOf*`` lists what an attribute admits), but an instance is
    not counted "as a" speed_select_type; that stays a vocabulary question.
    A plain dict, not a networkx graph: every load computes this, and importing
    networkx would add a tenth of a second to each command.
    """
    parents: dict[str, set[str]] = {e.name: set(e.supertypes) for e in model.entities.values()}
    for c in ANALYSIS_CLASSES:
        for member in c.members:
            parents.setdefault(member, set()).add("sga:" + c.name)
    return parents


def _ancestors(parents: dict[str, set[str]], name: str) -> set[str]:
    """Every class above ``name`` (the supertype graph is acyclic; each class visited once)."""
    found: set[str] = set()
    stack = list(parents.get(name, ()))
    while stack:
        current = stack.pop()
        if current not in found:
            found.add(current)
            stack.extend(parents.get(current, ()))
    return found


def _is_list(model: SchemaModel, t: TypeRef) -> bool:
    """Whether values of ``t`` are ``rdf:List`` s: an aggregate other than a top-level SET
    (:mod:`stepnc_graph.vocabulary.typemap`'s rule, without importing rdflib into every load)."""
    base = model.base_type(t)
    return isinstance(base, AggregateType) and base.kind != "SET"


def _iri(naming: Naming, name: str) -> str:
    return f"<{ANALYSIS_NS}{name[4:]}>" if name.startswith("sga:") else f"<{naming.declaration_iri(name)}>"


def compile_rules(model: SchemaModel, naming: Naming) -> DeriveRules:
    """Tables of the derivation for ``model``: which classes, properties and lists count."""
    derived = derived_entities(model)
    entities = [e for e in model.entities.values() if e.name in derived]
    is_a = _is_a(model)
    closure = {e.name: tuple(sorted(_ancestors(is_a, e.name))) for e in entities}
    generic: dict[str, str] = {}
    lists: list[str] = []
    labels: list[str] = []
    for e in entities:
        for a in e.explicit:
            prop = naming.attribute_iri(e.name, a.name)
            generic[prop] = generic_attribute_iri(a.name)
            if _is_list(model, a.type):
                lists.append(prop)
            if a.name == "its_id":
                labels.append(prop)
    superclasses = {naming.declaration_iri(c): tuple(_iri(naming, s)[1:-1] for s in ss) for c, ss in closure.items()}
    construct, blank_values = _layer_queries(generic, superclasses, labels)
    executable = set(model.all_subtypes("executable"))
    return DeriveRules(
        construct=construct,
        blank_values=blank_values,
        list_properties=tuple(sorted(lists)),
        workingsteps=frozenset(n for n in executable if model.is_subtype(n, "workingstep")),
        structures=frozenset(n for n in executable if model.is_subtype(n, "program_structure")),
        operation_properties=tuple(sorted(p for p, g in generic.items() if g.endswith("#its_operation"))),
        tool_properties=tuple(sorted(p for p, g in generic.items() if g.endswith("#its_tool"))),
        executables=tuple(sorted(n for n in executable if not model.entity(n).abstract)),
        superclasses=superclasses,
        generic=generic,
        labels=frozenset(labels),
    )


def _layer_queries(generic: dict[str, str], superclasses: dict[str, tuple[str, ...]],
                   labels: Iterable[str]) -> tuple[str, str]:
    """The CONSTRUCT of closure, generic values and labels, and the SELECT of the generic values
    that are blank nodes (see :class:`DeriveRules`), for these tables (IRIs)."""
    pairs = " ".join(f"(<{p}> <{g}>)" for p, g in sorted(generic.items()))
    supers = " ".join(f"(<{c}> <{s}>)" for c, ss in sorted(superclasses.items()) for s in ss)
    # Blank nodes (list heads, typed values) cannot travel as N-Triples text:
    # Oxigraph gives each parsed document fresh blank nodes. So values that are
    # blank nodes are selected apart (``blank_values``) and written as quads.
    construct = (
        f"CONSTRUCT {{ ?s ?q ?o }} WHERE {{\n"
        f"  {{ VALUES (?p ?q) {{ {pairs} }} ?s ?p ?o FILTER(!isBlank(?o)) }}\n"
        f"  UNION {{ VALUES (?c ?o) {{ {supers} }} ?s a ?c BIND({RDF_TYPE} AS ?q) }}\n"
        f"  UNION {{ VALUES ?p {{ {' '.join(f'<{p}>' for p in sorted(labels))} }} ?s ?p ?o "
        f"FILTER(STRLEN(?o) > 0) BIND({RDFS_LABEL} AS ?q) }}\n}}")
    blank_values = f"SELECT ?s ?q ?o WHERE {{ VALUES (?p ?q) {{ {pairs} }} ?s ?p ?o FILTER(isBlank(?o)) }}"
    return construct, blank_values


@lru_cache(maxsize=4)
def edition_rules(editions: frozenset[str]) -> DeriveRules:
    """The rules for a graph holding instances of ``editions``: the shipped rules, with the
    closure and generic properties of each edition's own terms (:func:`edition_tables`)."""
    rules = iso14649_rules()
    supers, generic = dict(rules.superclasses), dict(rules.generic)
    for edition in sorted(editions - {SHIPPED}):
        tables = edition_tables(edition)
        supers.update(tables.superclasses)
        generic.update(tables.generic)
    if supers == rules.superclasses and generic == rules.generic:
        return rules
    construct, blank_values = _layer_queries(generic, supers, rules.labels)
    return dataclasses.replace(rules, construct=construct, blank_values=blank_values, superclasses=supers,
                               generic=generic)


def graph_editions(store: Store, graph: str) -> frozenset[str]:
    """The editions a loaded graph's instances were read in (``p21:edition`` on it and on them)."""
    rows = store.query(f"SELECT DISTINCT ?e WHERE {{ GRAPH <{graph}> {{ ?s <{P21_NS}edition> ?e }} }}")
    return frozenset(str(r[0].value) for r in rows)


@lru_cache(maxsize=1)
def iso14649_rules() -> DeriveRules:
    """The rules for the shipped ISO 14649 model."""
    from stepnc_graph.schema.catalog import iso14649

    catalog, model = iso14649()
    return compile_rules(model, catalog.naming)


@lru_cache(maxsize=4)
def edition_tables(edition: str) -> DerivedTables:
    """The derived layer's tables (:class:`~stepnc_graph.mapping.mapper.DerivedTables`) for programs
    of ``edition``: the shipped ones, with the edition's classes closed over their 2002 counterpart
    and the edition's own properties given their generic ``attr:`` property."""
    tables = iso14649_rules().tables()
    if check_edition(edition) == SHIPPED:
        return tables
    supers = dict(tables.superclasses)
    generic = dict(tables.generic)
    for term in edition_terms(edition):
        if term.plan is None:
            continue
        if term.slot is not None:
            generic[term.iri] = generic_attribute_iri(term.slot.name)
        elif term.shipped is not None and term.shipped in supers:
            supers[term.iri] = (term.shipped, *supers[term.shipped])
    return dataclasses.replace(tables, superclasses=supers, generic=generic)


# -- reading the loaded graph --------------------------------------------------


Term = ox.NamedNode | ox.BlankNode | ox.Literal | ox.Triple


def superclasses(class_iri: str, rules: DeriveRules | None = None) -> tuple[str, ...]:
    """The superclasses the derived layer gives an instance of ``class_iri`` (empty for resources)."""
    return (rules or iso14649_rules()).superclasses.get(class_iri, ())
