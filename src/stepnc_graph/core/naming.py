"""Every IRI stepnc-graph mints is minted here.

Scheme (documented in ``ontology/README.md``, stable for good):

* vocabulary terms live in one namespace, ``.../iso14649#``, whatever schema
  declares them (names are unique across the model, and analysts should not
  need to know which part of ISO 14649 a term comes from to write a query);
* a local name is the EXPRESS name in lower case: ``stepnc:outer_diameter``;
* members are scoped by their owner with a dot: the attribute ``its_id`` of
  ``machining_operation`` is ``stepnc:machining_operation.its_id``; the
  enumeration item ``tcp`` of ``feedrate_reference`` is
  ``stepnc:feedrate_reference.tcp`` (entity/type names never contain dots, so
  the two cannot collide);
* each schema is an ontology ``.../iso14649/<schema_name>``;
* Part 21 structure (ids, lines, unset list members, ...) uses the ``p21:``
  vocabulary of :mod:`stepnc_graph.vocabulary.p21`;
* a loaded file is one named graph; its IRI is the *base IRI* (by default
  ``.../data/<file name>``, or ``--base-iri``) and the instance ``#12`` of it is
  ``<base IRI>/i12`` (``<base IRI>i12`` when the base ends in ``/`` or ``#``):
  the same file content and base IRI always give the same IRIs;
* stepnc-graph's own terms for querying live outside the ISO namespace: one
  generic property per EXPRESS attribute name, ``.../attribute#its_id``
  (prefix ``attr:``; every ``stepnc:<entity>.its_id`` is a sub-property of
  it), and the analysis vocabulary ``.../analysis#`` (prefix ``sga:``) for
  what the standard leaves implicit (roughing and finishing operations, the
  execution order); a file's derived layer is the graph ``<base IRI>/derived``
  and its execution steps are ``<base IRI>/derived/step<n>``;
* an instance with an ``its_id`` label that no other instance of the same
  scope shares also gets an alias ``<base IRI>/id/<scope>/<its_id>``
  (percent-encoded; the scope is the entity declaring ``its_id``, such as
  ``executable`` or ``manufacturing_feature``), ``owl:sameAs`` the instance:
  a link for PLM systems that survives renumbering of the instance ids;
* the links a mapping file attaches to a program's instances live in their own
  named graph ``<base IRI>/links/<mapping file name>`` (percent-encoded).

**Graph names a program reserves.** A program graph ``G`` owns the names of its companion graphs:
``G/derived``, every name under ``G/derived/`` and every name under ``G/links/`` (its *companion
namespace*, :func:`companion_names`). Two programs whose names would share one of these (``G`` and
``G/derived``, ``G`` and ``G/links/x``, ``G`` and ``G/``: both derived layers are ``G/derived``) cannot
both be in a store, and no program, link graph or user graph may take the vocabulary graph or a
name under :data:`STAGING` (the graphs a running write stages its data in). :class:`GraphLayout`
applies these rules to a store, knowing which graph is what from the store's own records.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import PurePath
from typing import TYPE_CHECKING, Any
from urllib.parse import quote

from stepnc_graph.core.errors import StepncGraphError

if TYPE_CHECKING:
    from rdflib import Namespace, URIRef

    from stepnc_graph.store.contract import Store

STEPNC_NS = "https://w3id.org/stepnc-graph/iso14649#"
ONTOLOGY_BASE = "https://w3id.org/stepnc-graph/iso14649/"
P21_NS = "https://w3id.org/stepnc-graph/p21#"
P21_ONTOLOGY = "https://w3id.org/stepnc-graph/p21"

#: Generic attribute properties, one per EXPRESS attribute name (prefix ``attr:``).
ATTRIBUTE_NS = "https://w3id.org/stepnc-graph/attribute#"
ATTRIBUTE_ONTOLOGY = "https://w3id.org/stepnc-graph/attribute"
#: The analysis vocabulary: terms for what ISO 14649 leaves implicit (prefix ``sga:``).
ANALYSIS_NS = "https://w3id.org/stepnc-graph/analysis#"
ANALYSIS_ONTOLOGY = "https://w3id.org/stepnc-graph/analysis"

DATA_BASE = "https://w3id.org/stepnc-graph/data/"
#: The named graph holding the vocabulary (ontology/*.ttl) in a store.
VOCABULARY_GRAPH = "https://w3id.org/stepnc-graph/iso14649"
TOOL_IRI = "https://w3id.org/stepnc-graph/tool/"
#: What the names of staging graphs start with: a write stages its data there and moves it into
#: place (an in-memory replacement, any load into a remote store). No other graph may be named so.
STAGING = "urn:stepnc-graph:staging:"
#: The IRI documents use to name the shipped JSON-LD context (``ontology/context.jsonld``).
#: stepnc-graph never fetches it: its reader serves it from the installed file.
CONTEXT_IRI = "https://w3id.org/stepnc-graph/context.jsonld"

#: ``STEPNC`` and ``P21`` are rdflib Namespaces over the two namespaces above,
#: made on first use (module ``__getattr__``): rdflib costs about 0.1 s to
#: import, and loading a program never needs it.
_NAMESPACES = {"STEPNC": STEPNC_NS, "P21": P21_NS, "ATTR": ATTRIBUTE_NS, "SGA": ANALYSIS_NS}

if TYPE_CHECKING:
    STEPNC: Namespace
    P21: Namespace
    ATTR: Namespace
    SGA: Namespace


def __getattr__(name: str) -> Any:
    if name in _NAMESPACES:
        from rdflib import Namespace

        value = Namespace(_NAMESPACES[name])
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _uri(value: str) -> URIRef:
    """An rdflib IRI; rdflib is imported here, on first use, not with this module."""
    from rdflib import URIRef

    return URIRef(value)


@dataclass(frozen=True)
class Naming:
    """IRI minting for one vocabulary namespace (the shipped one by default)."""

    namespace: str = STEPNC_NS
    ontology_base: str = ONTOLOGY_BASE

    def declaration(self, name: str) -> URIRef:
        """An entity, defined type, enumeration or select."""
        return _uri(self.declaration_iri(name))

    def declaration_iri(self, name: str) -> str:
        """:meth:`declaration` as a plain string (no rdflib: for code on a load's path)."""
        return self.namespace + name.lower()

    def attribute(self, entity: str, attribute: str) -> URIRef:
        return _uri(self.attribute_iri(entity, attribute))

    def attribute_iri(self, entity: str, attribute: str) -> str:
        """:meth:`attribute` as a plain string (no rdflib)."""
        return f"{self.namespace}{entity.lower()}.{attribute.lower()}"

    def enum_item(self, enumeration: str, item: str) -> URIRef:
        return _uri(f"{self.namespace}{enumeration.lower()}.{item.lower()}")

    def ontology(self, schema: str) -> URIRef:
        return _uri(self.ontology_base + schema.lower())

    def ontology_version(self, schema: str, version: str) -> URIRef:
        return _uri(f"{self.ontology_base}{schema.lower()}/{version}")

    def local_name(self, iri: str) -> str | None:
        """The local part of a vocabulary IRI, or None for a foreign IRI."""
        return iri[len(self.namespace):] if iri.startswith(self.namespace) else None


def default_graph_iri(path: str) -> str:
    """The graph IRI of a file loaded without ``--base-iri``: from its file name."""
    return DATA_BASE + quote(PurePath(path).name, safe="")


def instance_prefix(graph_iri: str) -> str:
    """What instance ids are appended to, for a graph IRI."""
    return graph_iri if graph_iri.endswith(("/", "#")) else graph_iri + "/"


def instance_iri(graph_iri: str, p21_id: int) -> str:
    return f"{instance_prefix(graph_iri)}i{p21_id}"


def instance_id(graph_iri: str, iri: str) -> int | None:
    """The #id of an instance IRI of ``graph_iri`` (the inverse of :func:`instance_iri`), else None."""
    head = instance_prefix(graph_iri) + "i"
    digits = iri[len(head):] if iri.startswith(head) else ""
    return int(digits) if digits.isdigit() and digits.isascii() else None


def derived_graph_iri(graph_iri: str) -> str:
    """The named graph that holds the derived (query) layer of a loaded file's graph.

    It lives beside the lossless program graph, is written in the same atomic
    load and removed with it, and the Part 21 writer never reads it.
    """
    return f"{instance_prefix(graph_iri)}derived"


def generic_attribute(name: str) -> URIRef:
    """The generic property of every attribute called ``name``, whatever entity declares it."""
    return _uri(generic_attribute_iri(name))


def generic_attribute_iri(name: str) -> str:
    """:func:`generic_attribute` as a plain string (no rdflib)."""
    return ATTRIBUTE_NS + name.lower()


def generic_attribute_of_kind(name: str, kind: str) -> URIRef:
    """The generic property of the attributes called ``name`` whose values are of one ``kind``
    (``literal`` or ``node``): ``attr:<name>.<kind>``, used where attributes of that name have
    both kinds (no EXPRESS name has a dot, so these never collide with :func:`generic_attribute`)."""
    return _uri(f"{generic_attribute_iri(name)}.{kind}")


def analysis_term(name: str) -> URIRef:
    """A term of the analysis vocabulary (``sga:RoughingOperation``, ``sga:next``, ...)."""
    return _uri(ANALYSIS_NS + name)


def execution_step_iri(graph_iri: str, index: int) -> str:
    """The ``index``-th (1-based) step of a file's flattened execution order, in its derived layer."""
    return f"{derived_graph_iri(graph_iri)}/step{index}"


def class_count_iri(graph_iri: str, index: int) -> str:
    """The ``index``-th (1-based) count of instances per class of a file, in its derived layer."""
    return f"{derived_graph_iri(graph_iri)}/count{index}"


def section_iri(graph_iri: str, index: int) -> str:
    """The ``index``-th (1-based) DATA section of a file that has several."""
    return f"{instance_prefix(graph_iri)}section{index}"


def link_graph_iri(graph_iri: str, mapping: str) -> str:
    """The named graph of the links one mapping file (``mapping``: its file name) attaches to a program."""
    return f"{link_graphs_prefix(graph_iri)}{quote(mapping, safe='')}"


def link_graphs_prefix(graph_iri: str) -> str:
    """What every link graph of a program starts with (see :func:`link_graph_iri`)."""
    return f"{instance_prefix(graph_iri)}links/"


def alias_iri(graph_iri: str, scope: str, label: str) -> str:
    """The alias of the one instance of ``scope`` whose its_id is ``label``."""
    return f"{instance_prefix(graph_iri)}id/{scope.lower()}/{quote(label, safe='')}"


# -- which graph names belong to whom ---------------------------------------------------------------


class GraphNameError(StepncGraphError, ValueError):
    """A graph name that would take the place of another graph of the store, or a reserved one."""


@dataclass(frozen=True)
class Names:
    """A set of graph names: some names, and every name that starts with one of ``prefixes``."""

    exact: frozenset[str] = frozenset()
    prefixes: tuple[str, ...] = ()

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and (name in self.exact or name.startswith(self.prefixes))

    def shared(self, other: "Names") -> str | None:
        """A name both sets hold (``prefix...`` for the names under a prefix of both), or None."""
        for name in sorted(self.exact):
            if name in other:
                return name
        for name in sorted(other.exact):
            if name in self:
                return name
        for a in self.prefixes:
            for b in other.prefixes:
                if a.startswith(b) or b.startswith(a):
                    return max(a, b, key=len) + "..."
        return None


def _show(name: str) -> str:
    """A name of :meth:`Names.shared` for a message."""
    return name if name.endswith("...") else f"<{name}>"


#: Names no graph of a user, a load or a link may take: the vocabulary graph and staging graphs.
RESERVED = Names(frozenset({VOCABULARY_GRAPH}), (STAGING,))


def companion_names(graph_iri: str) -> Names:
    """The companion namespace of the program graph ``graph_iri``: its derived layer, the names
    under it, and the names of its link graphs (see the module docstring)."""
    derived = derived_graph_iri(graph_iri)
    return Names(frozenset({derived}), (derived + "/", link_graphs_prefix(graph_iri)))


def program_names(graph_iri: str) -> Names:
    """The names a program graph takes in a store: its own and its companion namespace."""
    companions = companion_names(graph_iri)
    return Names(companions.exact | {graph_iri}, companions.prefixes)


def refuse_reserved(graph_iri: str) -> None:
    """:class:`GraphNameError` for the vocabulary graph and staging names (see :data:`RESERVED`)."""
    if graph_iri == VOCABULARY_GRAPH:
        raise GraphNameError(f"<{graph_iri}> is reserved for the vocabulary graph, which stepnc-graph writes "
                             "itself: it is not a program or a link graph")
    if graph_iri.startswith(STAGING):
        raise GraphNameError(f"<{graph_iri}> is reserved: graphs under {STAGING} stage the data of a running write")


def refuse_strangers(graph_iri: str, companions: Iterable[str]) -> None:
    """:class:`GraphNameError` unless ``graph_iri`` is not reserved and each of ``companions`` lies in
    its companion namespace: what a store checks before it writes or removes them together."""
    refuse_reserved(graph_iri)
    own = companion_names(graph_iri)
    for name in companions:
        if name not in own:
            raise GraphNameError(f"<{name}> is not a companion graph of <{graph_iri}> (its derived layer or one of "
                                 "its link graphs); it is not written or removed with it")


def _role(name: str, program: str) -> str:
    """What ``name`` is, or would be, for the program graph ``program`` (inside its names)."""
    derived = derived_graph_iri(program)
    if name == program:
        return f"the program graph <{program}>"
    if name == derived:
        return f"the derived layer of <{program}>"
    if name.startswith(derived + "/"):
        return f"a name under the derived layer of <{program}>"
    return f"the name of a link graph of <{program}>"


@dataclass(frozen=True)
class GraphLayout:
    """What each named graph of a store is, from the store's own records: a program graph says
    ``<G> a p21:ExchangeStructure`` in itself, a link graph ``<L> a p21:LinkGraph ;
    p21:linkedProgram <G>``; a program's derived layer is the graph its name gives, unless that
    graph records itself as something else. Never from a name's shape alone: a program may be
    called ``.../derived`` or ``.../links/x`` when no other program claims that name.

    The rules (see the module docstring): the names of two programs (:func:`program_names`) never
    meet; a program's companion namespace holds only its own derived layer and link graphs; a
    link graph lies in its program's namespace and in no other's; nothing takes a
    :data:`RESERVED` name. Each check raises :class:`GraphNameError` naming both graphs.
    """

    #: every named graph but staging ones
    names: frozenset[str]
    #: the program graphs
    programs: frozenset[str]
    #: link graph -> the program it links
    links: Mapping[str, str] = field(default_factory=dict)

    @cached_property
    def derived_layers(self) -> dict[str, str]:
        """derived layer -> its program, for the programs' derived layers in the store."""
        found = {derived_graph_iri(p): p for p in self.programs}
        return {d: p for d, p in found.items() if d in self.names and d not in self.programs and d not in self.links}

    def listed(self) -> list[str]:
        """The graphs a user names (programs, link graphs, graphs users added): not the vocabulary,
        nor a program's derived layer."""
        return sorted(self.names - {VOCABULARY_GRAPH} - set(self.derived_layers))

    def owner(self, name: str) -> str | None:
        """The program ``name`` belongs to (itself for a program), or None."""
        if name in self.programs:
            return name
        return self.links.get(name) or self.derived_layers.get(name)

    def role(self, name: str) -> str:
        """What the graph ``name`` of the store is, for messages."""
        if name == VOCABULARY_GRAPH:
            return "the vocabulary graph"
        if name in self.programs:
            return f"the program graph <{name}>"
        if name in self.links:
            return f"a link graph of <{self.links[name]}>"
        if (program := self.derived_layers.get(name)) is not None:
            return f"the derived layer of <{program}>"
        return f"the graph <{name}> (no load or link wrote it)"

    def refuse_programs(self, graphs: Sequence[str]) -> None:
        """Refuse to load the program graphs ``graphs`` (one command's) when a name of one of them
        would take the place of a graph of the store or of another of them."""
        for k, graph in enumerate(graphs):
            self.refuse_program(graph)
            for other in graphs[k + 1:]:
                if other != graph and (name := program_names(graph).shared(program_names(other))) is not None:
                    raise GraphNameError(f"<{graph}> and <{other}> cannot both be loaded: {_show(name)} would be both "
                                         f"{_role(name, graph)} and {_role(name, other)}; give each its own --base-iri")

    def refuse_program(self, graph: str) -> None:
        """Refuse to load (or replace) the program graph ``graph`` when one of its names is reserved,
        is another program's, or is held by a graph that does not belong to it."""
        refuse_reserved(graph)
        mine = program_names(graph)
        if (name := mine.shared(RESERVED)) is not None:
            raise GraphNameError(f"<{graph}> cannot be loaded: {_show(name)} would be {_role(name, graph)}, a "
                                 "reserved name")
        if graph in self.names and self.owner(graph) not in (None, graph):
            raise GraphNameError(f"<{graph}> cannot be loaded: the name is reserved for {self.role(graph)}; choose "
                                 "another --base-iri")
        for other in sorted(self.programs - {graph}):
            if (name := mine.shared(program_names(other))) is not None:
                raise GraphNameError(f"<{graph}> cannot be loaded beside the program <{other}>: {_show(name)} would "
                                     f"be both {_role(name, graph)} and {_role(name, other)}; choose another "
                                     "--base-iri")
        for name in sorted(self.names - {graph}):
            if name in mine and self.owner(name) != graph:
                raise GraphNameError(f"<{graph}> cannot be loaded: <{name}> would be {_role(name, graph)}, but the "
                                     f"store holds it as {self.role(name)}; choose another --base-iri")

    def refuse_link(self, link: str, program: str) -> None:
        """Refuse to write the link graph ``link`` of ``program`` unless ``program`` is a program graph,
        ``link`` lies in its companion namespace and in no other program's, and no graph but a link
        graph of ``program`` holds that name."""
        if program not in self.programs:
            raise GraphNameError(f"<{program}> is not a program graph (it is {self.role(program)}); links attach to "
                                 "a loaded program's instances (see `stepnc-graph info`)")
        if link not in companion_names(program):
            raise GraphNameError(f"<{link}> is not a link graph's name of <{program}>")
        for other in sorted(self.programs - {program}):
            if link in program_names(other):
                raise GraphNameError(f"the link graph <{link}> of <{program}> would be {_role(link, other)}; rename "
                                     "the mapping file")
        if link in self.names and self.links.get(link) != program:
            raise GraphNameError(f"the link graph <{link}> of <{program}> would replace {self.role(link)}; rename the "
                                 "mapping file")

    def unloaded_with(self, graph: str) -> tuple[str, ...]:
        """The graphs an unload of ``graph`` removes with it: a program's derived layer and link
        graphs (by the store's records, never another program's graph); nothing for a link graph or
        a graph a user added. Refuses the reserved graphs and a program's derived layer, which go
        with their program."""
        refuse_reserved(graph)
        layers = self.derived_layers
        if graph in layers:
            raise GraphNameError(f"<{graph}> is the derived layer of <{layers[graph]}>: it goes with its program "
                                 f"(unload <{layers[graph]}>)")
        if graph not in self.programs:
            return ()
        derived = derived_graph_iri(graph)
        return (*([derived] if layers.get(derived) == graph else []), *self.links_of(graph))

    def links_of(self, program: str) -> list[str]:
        """The link graphs that record ``program`` as theirs, sorted: in its companion namespace,
        where `link` names them, and none of them a program."""
        own = companion_names(program)
        return sorted(name for name, owner in self.links.items()
                      if owner == program and name in own and name not in self.programs)


def graph_layout(store: Store) -> GraphLayout:
    """What each named graph of ``store`` is, from its records (:class:`GraphLayout`): the program
    graphs (``p21:ExchangeStructure``) and the link graphs with their program (``p21:LinkGraph``,
    ``p21:linkedProgram``). One query, answered from the indexes of those two classes, on any store.
    The one place that decides which graphs are programs: stores know graphs, not programs."""
    import pyoxigraph as ox

    rows = store.query(f"SELECT ?g ?program WHERE {{ GRAPH ?g {{ {{ ?g a <{P21_NS}ExchangeStructure> }} UNION "
                       f"{{ ?g a <{P21_NS}LinkGraph> ; <{P21_NS}linkedProgram> ?program }} }} }}")
    programs: set[str] = set()
    links: dict[str, str] = {}
    for row in rows:
        graph, program = row[0], row[1]
        if not isinstance(graph, ox.NamedNode):
            continue
        if program is None:
            programs.add(graph.value)
        elif isinstance(program, ox.NamedNode):
            links[graph.value] = program.value
    return GraphLayout(frozenset(store.all_graphs()), frozenset(programs), links)


def program_graphs(store: Store) -> list[str]:
    """The graphs of loaded files (``p21:ExchangeStructure``), sorted: not the vocabulary,
    derived layers, link graphs or other graphs a user added."""
    return sorted(graph_layout(store).programs)


def listed_graphs(store: Store) -> list[str]:
    """The graphs a user names (:meth:`GraphLayout.listed`): the loaded files' graphs, link graphs
    and graphs users added; not staging graphs, the vocabulary graph or a derived layer."""
    return graph_layout(store).listed()
