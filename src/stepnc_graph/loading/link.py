"""Links from a program's instances to PLM data: part numbers, tool catalogue numbers, document IDs.

A mapping file (CSV or JSON) names program entities -- by ``its_id`` (optionally
with the entity it belongs to, ``scope``) or by ``#id`` (``p21_id``) -- and gives
each a PLM ``identifier`` (a literal, written ``dcterms:identifier``) and/or a
PLM IRI (``same_as``, written ``owl:sameAs``). :func:`link` writes them into a
named graph of their own, ``<program graph>/links/<mapping file name>``
(:func:`~stepnc_graph.core.naming.link_graph_iri`), so the program graph stays as it
was loaded and its Part 21 round trip is untouched.

* An entity found by ``its_id`` is linked through its alias
  ``<graph>/id/<scope>/<its_id>`` (``owl:sameAs`` the instance in the program
  graph), which a later load of a renumbered file gives again: the links
  survive a CAM system renumbering the ``#id``\\ s. An entity found by ``#id`` is
  linked by its instance IRI.
* Every row must match exactly one entity. Unknown or ambiguous rows are
  reported with their line; by default nothing is written then
  (:class:`LinkError`, exit 2), with ``allow_unknown`` the rows that match are
  written and the others reported (exit 1).
* A link graph records its own provenance: ``p21:LinkGraph``, the program it
  links (``p21:linkedProgram``), the mapping file (``dcterms:source``,
  ``prov:hadPrimarySource``, ``p21:sha256``), when (``prov:generatedAtTime``)
  and the activity that wrote it.
* Linking the same mapping file again replaces its graph; a mapping of another
  path with the same file name is only replaced with ``replace``. Reloading the
  program keeps its link graphs; unloading it removes them
  (:func:`program_link_graphs`).
"""

from __future__ import annotations

import hashlib
from collections import defaultdict
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.errors import listed_by, option
from stepnc_graph.core.version import __version__
from stepnc_graph.loading.common import DCT, PROV, RDFS, load_timestamp
from stepnc_graph.mapping.plans import Plans, iso14649_plans
from stepnc_graph.core.naming import (
    P21_NS,
    TOOL_IRI,
    alias_iri,
    instance_prefix,
    link_graph_iri,
)
from stepnc_graph.loading.common import SourceError
from stepnc_graph.core.naming import graph_layout, program_graphs
from stepnc_graph.store.contract import Store
from stepnc_graph.loading.link_mapping import COLUMNS, LinkError, Problem, Row, read_mapping

__all__ = ["COLUMNS", "LinkError", "LinkResult", "Problem", "Row", "link", "program_link_graphs", "read_mapping"]


OWL_SAME_AS = "http://www.w3.org/2002/07/owl#sameAs"
RDF_TYPE = "http://www.w3.org/1999/02/22-rdf-syntax-ns#type"
XSD_INTEGER = "http://www.w3.org/2001/XMLSchema#integer"


@dataclass
class LinkResult:
    """What one mapping linked: ``links`` rows written, ``problems`` rows that were not."""

    mapping: str
    graph: str
    link_graph: str
    links: int = 0
    triples: int = 0
    problems: list[Problem] = field(default_factory=list)

    def asdict(self) -> dict[str, Any]:
        return {"mapping": self.mapping, "graph": self.graph, "link_graph": self.link_graph, "links": self.links,
                "triples": self.triples, "problems": [p.asdict() for p in self.problems]}


@dataclass(frozen=True)
class Labelled:
    """An instance with an its_id: its IRI, ``#id``, the its_id's scope and the instance's entity names."""

    iri: str
    p21_id: int | None
    scope: str
    entities: tuple[str, ...]


class ProgramIndex:
    """The program's instances by ``#id`` and by its_id, read once from the store."""

    def __init__(self, store: Store, graph: str, plans: Plans) -> None:
        self.graph, self.plans = graph, plans
        g = ox.NamedNode(graph)
        self.ids = {int(str(q.object.value)): q.subject.value  # type: ignore[union-attr]
                    for q in store.quads_for_pattern(None, ox.NamedNode(P21_NS + "id"), None, g)}
        number = {iri: n for n, iri in self.ids.items()}
        scopes = {plan.slots[plan.its_id].prop: plan.slots[plan.its_id].entity
                  for plan in plans.entities.values() if plan.its_id is not None}
        self.labels: dict[str, list[Labelled]] = defaultdict(list)
        for prop, scope in sorted(scopes.items()):
            for q in store.quads_for_pattern(None, ox.NamedNode(prop), None, g):
                if isinstance(q.object, ox.Literal) and isinstance(q.subject, ox.NamedNode):
                    classes = [t.object.value for t in store.quads_for_pattern(q.subject, ox.NamedNode(RDF_TYPE), None, g)
                               if isinstance(t.object, ox.NamedNode)]
                    types = tuple(sorted(self.plans.by_class[c].name for c in classes if c in self.plans.by_class))
                    self.labels[q.object.value].append(
                        Labelled(q.subject.value, number.get(q.subject.value), scope, types))
        self.aliases = {q.subject.value for q in store.quads_for_pattern(None, ox.NamedNode(OWL_SAME_AS), None, g)
                        if isinstance(q.subject, ox.NamedNode)}

    def subject(self, row: Row) -> str:
        """The IRI to link for ``row``, or ValueError saying why there is none."""
        if row.p21_id is not None:
            if row.p21_id not in self.ids:
                raise ValueError(f"the program has no instance #{row.p21_id}")
            return self.ids[row.p21_id]
        assert row.its_id is not None
        found = self.labels.get(row.its_id, [])
        if row.scope is not None:
            found = self._in_scope(found, row.scope)
        if not found:
            raise ValueError("no instance of the program has this its_id" + (
                f" in scope {row.scope}" if row.scope else ""))
        if len(found) > 1:
            which = ", ".join(f"#{f.p21_id} {'+'.join(f.entities)}" for f in found)
            hint = "add a scope or give the p21_id" if len({f.scope for f in found}) > 1 else "give the p21_id"
            raise ValueError(f"{len(found)} instances have this its_id ({which}); {hint}")
        [entity] = found
        alias = alias_iri(self.graph, entity.scope, row.its_id)
        return alias if alias in self.aliases else entity.iri

    def _in_scope(self, found: list[Labelled], scope: str) -> list[Labelled]:
        plan = self.plans.entities.get(scope.upper())
        if plan is None:
            raise ValueError(f"scope {scope!r} is not an entity of the schema")
        model = self.plans.model
        return [f for f in found if any(model.is_subtype(e, plan.name) or e == plan.name for e in f.entities)]


# -- writing the link graph -------------------------------------------------------------------------


def program_link_graphs(store: Store, graph: str) -> list[str]:
    """The link graphs of a program graph (what unloading it removes with it): those that record
    it as their program (``p21:linkedProgram``), never a graph whose name only looks like one."""
    return graph_layout(store).links_of(graph)


def _only_program(store: Store) -> str:
    graphs = program_graphs(store)
    if len(graphs) != 1:
        raise SourceError(f"the store holds {len(graphs)} programs; choose one with {option('graph')} "
                          f"({listed_by()})")
    return graphs[0]


def link(store: Store, mapping: str | Path, graph: str | None = None, *, allow_unknown: bool = False,
         replace: bool = False) -> LinkResult:
    """Attach the PLM identifiers of ``mapping`` to the instances of the program ``graph``
    (default: the store's only program), in the link graph of that mapping, atomically.

    Raises :class:`LinkError` when the mapping cannot be read or (unless
    ``allow_unknown``) a row matches no single entity -- the store is then unchanged --
    and :class:`~stepnc_graph.loading.sources.SourceError` for an unknown graph or a link
    graph that holds another mapping file (unless ``replace``);
    :class:`~stepnc_graph.core.naming.GraphNameError` when ``graph`` is not a program, or the link
    graph's name is another graph's (:meth:`~stepnc_graph.core.naming.GraphLayout.refuse_link`).
    """
    path = Path(mapping)
    raw = path.read_bytes()
    store.prepare_to_write()  # the checks below read the newest published state
    graph = graph if graph is not None else _only_program(store)
    if not store.has_graph(graph):
        raise SourceError(f"no graph {graph} in the store (see `stepnc-graph info`)")
    target = link_graph_iri(graph, path.name)
    graph_layout(store).refuse_link(target, graph)
    _refuse_other_mapping(store, target, path, replace)
    rows, problems = read_mapping(path)
    total = len(rows) + len(problems)
    index = ProgramIndex(store, graph, iso14649_plans())
    lines: list[str] = []
    result = LinkResult(str(path), graph, target)
    for row in rows:
        try:
            subject = index.subject(row)
        except ValueError as e:
            problems.append(Problem(row.line, row.key(), str(e)))
            continue
        result.links += 1
        if row.same_as is not None:
            lines.append(f"<{subject}> <{OWL_SAME_AS}> <{row.same_as}> .\n")
        if row.identifier is not None:
            lines.append(f"<{subject}> <{DCT}identifier> {ox.Literal(row.identifier)} .\n")
    result.problems = sorted(problems, key=lambda p: p.line)
    if result.problems and not allow_unknown:
        raise LinkError(str(path), f"{len(result.problems)} of {total} rows are malformed or match no single entity "
                                   f"of <{graph}>; nothing was linked ({option('allow_unknown', 'True')} links the others)",
                        result.problems)
    lines = list(dict.fromkeys(lines)) + _provenance(target, graph, path, raw)
    result.triples = len(lines)
    store.replace_graph(target, _chunks(lines))
    return result


def _refuse_other_mapping(store: Store, target: str, path: Path, replace: bool) -> None:
    if replace or not store.has_graph(target):
        return
    node = ox.NamedNode(target)
    held = [q.object.value for q in store.quads_for_pattern(node, ox.NamedNode(DCT + "source"), None, node)
            if isinstance(q.object, ox.Literal)]
    if held and str(path.resolve()) not in held:
        raise SourceError(f"link graph <{target}> holds the links of {held[0]}, not {path.resolve()}; pass {option('replace', 'True')} "
                          "to replace them, or rename the mapping file")


def _provenance(target: str, graph: str, path: Path, raw: bytes) -> list[str]:
    """The link graph describes itself: what it links, from which file, when, by what."""
    g, uri = f"<{target}>", f"<{path.resolve().as_uri()}>"
    now = load_timestamp()
    activity, tool = f"<{instance_prefix(target)}link>", f"<{TOOL_IRI}{__version__}>"
    return [f"{g} <{RDF_TYPE}> <{P21_NS}LinkGraph> .\n", f"{g} <{RDF_TYPE}> <{PROV}Entity> .\n",
            f"{g} <{P21_NS}linkedProgram> <{graph}> .\n",
            f"{g} <{DCT}source> {ox.Literal(str(path.resolve()))} .\n", f"{g} <{PROV}hadPrimarySource> {uri} .\n",
            f"{g} <{P21_NS}sha256> {ox.Literal(hashlib.sha256(raw).hexdigest())} .\n",
            f"{g} <{PROV}generatedAtTime> {now} .\n", f"{g} <{PROV}wasGeneratedBy> {activity} .\n",
            f"{activity} <{RDF_TYPE}> <{PROV}Activity> .\n", f"{activity} <{PROV}used> {uri} .\n",
            f"{activity} <{PROV}used> <{graph}> .\n", f"{activity} <{PROV}wasAssociatedWith> {tool} .\n",
            f"{activity} <{PROV}endedAtTime> {now} .\n", f"{tool} <{RDF_TYPE}> <{PROV}SoftwareAgent> .\n",
            f"{tool} <{RDFS}label> {ox.Literal('stepnc-graph ' + __version__)} .\n"]


def _chunks(lines: list[str], size: int = 20000) -> Iterator[str]:
    for start in range(0, len(lines), size):
        yield "".join(lines[start:start + size])
