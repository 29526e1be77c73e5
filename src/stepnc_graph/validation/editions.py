"""Validating programs of another edition of ISO 14649 with the shipped (2002) shapes.

The shapes are generated from the 2002 schemas. A program read in another edition
(:mod:`stepnc_graph.mapping.editions`) shares their vocabulary where the editions mean the same,
and its own classes are subclasses of their 2002 counterparts in the shapes' class hierarchy
(``shapes/support.ttl``), so the 2002 shapes check a 2001 ``CENTER_DRILL`` as a ``centerdrill``.
What the 2002 shapes require of an attribute the program's edition does not have for that entity
(the 2002 ``boring_tool.retract_movement_forbidden`` of a 2001 ``BORING_TOOL``) is no rule of that
edition: :func:`edition_rules` drops those results, for each instance by the edition it was read in
(its ``p21:edition``, else its file's).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.core.naming import P21_NS
from stepnc_graph.mapping.editions import SHIPPED, edition_plans

if TYPE_CHECKING:
    from stepnc_graph.validation.report import Result


def _editions(store: ox.Store, graph: str) -> tuple[str, dict[str, str]]:
    """The graph's edition and, per instance read in another one, that edition."""
    g = ox.NamedNode(graph)
    own = SHIPPED
    others: dict[str, str] = {}
    for q in store.quads_for_pattern(None, ox.NamedNode(P21_NS + "edition"), None, g):
        s, e = q.subject, q.object
        if isinstance(e, ox.Literal):
            if s == g:
                own = e.value
            elif isinstance(s, ox.NamedNode):
                others[s.value] = e.value
    return own, others


def edition_rules(store: ox.Store, graph: str, results: list[Result]) -> list[Result]:
    """``results`` without those that hold an instance of another edition than 2002 to a 2002
    attribute its edition does not give its entity."""
    own, others = _editions(store, graph)
    if own == SHIPPED and not others:
        return results
    kept = []
    for r in results:
        edition = others.get(r.focus, own)
        if edition == SHIPPED or not _absent_attribute(store, graph, r, edition):
            kept.append(r)
    return kept


def _absent_attribute(store: ox.Store, graph: str, r: Result, edition: str) -> bool:
    """Whether ``r`` is about a property that no entity the focus is typed with has in ``edition``
    while the 2002 vocabulary has it (a constraint of an attribute the edition lacks)."""
    path = r.path_iri or ""
    if not (path.startswith("<") and path.endswith(">")):
        return False
    prop = path[1:-1]
    if r.focus_term is not None and not r.focus_term.startswith("<"):
        return False  # a blank node (a list cell, a typed value): no entity of its own
    plans = edition_plans(edition)
    classes = [q.object.value for q in store.quads_for_pattern(
        ox.NamedNode(r.focus), ox.NamedNode("http://www.w3.org/1999/02/22-rdf-syntax-ns#type"), None,
        ox.NamedNode(graph)) if isinstance(q.object, ox.NamedNode)]
    entity_plans = [plans.by_class[c] for c in classes if c in plans.by_class]
    if not entity_plans:
        return False
    shipped = edition_plans(SHIPPED)
    in_2002 = any(prop in {s.prop for s in p.slots} for c in classes if (p := shipped.by_class.get(c)) is not None)
    return in_2002 and all(prop not in {s.prop for s in p.slots} for p in entity_plans)
