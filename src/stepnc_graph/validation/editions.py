"""Validating programs of another edition of ISO 14649 with the shipped (2002) shapes.

The shapes are generated from the 2002 schemas. A program read in another edition
(:mod:`stepnc_graph.mapping.editions`) shares their vocabulary where the editions mean the same,
and its own classes are subclasses of their 2002 counterparts in the shapes' class hierarchy
(``shapes/support.ttl``), so the 2002 shapes check a 2001 ``CENTER_DRILL`` as a ``centerdrill``.
What the 2002 shapes require of an attribute the program's edition does not have for that entity
(the 2002 ``boring_tool.retract_movement_forbidden`` of a 2001 ``BORING_TOOL``) is no rule of that
edition: :func:`edition_rules` drops those results, for each instance by the edition it was read in
(its ``p21:edition``, else its file's).

A WHERE rule the edition has otherwise than 2002 (or not at all) is another matter: the build
compiles each such rule of the edition into a shape of its own (``shapes/edition_<edition>.ttl``,
:mod:`stepnc_graph.generators.edition_shapes`) marked ``shapes:edition``, and marks the 2002 shape
it differs from ``shapes:notForEdition``. :func:`edition_rules` keeps a result of an edition's shape
only for an instance of that edition, and a result of a 2002 shape only for an instance of an
edition it holds for: each instance is checked by its own edition's rule.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path
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


#: the shapes' vocabulary (:data:`stepnc_graph.generators.shacl.SHAPES_NS`)
_SHAPES_NS = "https://w3id.org/stepnc-graph/shapes#"
#: what names an edition's rule shapes (:data:`stepnc_graph.generators.edition_shapes.FILE`)
_EDITION_FILES = "edition_*.ttl"


@lru_cache(maxsize=8)
def _edition_marks(files: tuple[tuple[str, float], ...]) -> tuple[dict[str, str], dict[str, frozenset[str]]]:
    """From the edition shape files (path, modification time): each edition shape's edition, and
    each 2002 shape's editions it does not hold for."""
    own: dict[str, str] = {}
    not_for: dict[str, set[str]] = {}
    for path, _ in files:
        store = ox.Store()
        store.load(path=path, format=ox.RdfFormat.TURTLE)
        for q in store.quads_for_pattern(None, ox.NamedNode(_SHAPES_NS + "edition"), None, None):
            if isinstance(q.subject, ox.NamedNode) and isinstance(q.object, ox.Literal):
                own[q.subject.value] = q.object.value
        for q in store.quads_for_pattern(None, ox.NamedNode(_SHAPES_NS + "notForEdition"), None, None):
            if isinstance(q.subject, ox.NamedNode) and isinstance(q.object, ox.Literal):
                not_for.setdefault(q.subject.value, set()).add(q.object.value)
    return own, {k: frozenset(v) for k, v in not_for.items()}


def edition_marks(shape_files: Sequence[Path]) -> tuple[dict[str, str], dict[str, frozenset[str]]]:
    """:func:`_edition_marks` of the edition shape files among ``shape_files``."""
    found = tuple((str(p), p.stat().st_mtime) for p in shape_files if p.match(_EDITION_FILES) and p.is_file())
    return _edition_marks(found) if found else ({}, {})


def edition_rules(store: ox.Store, graph: str, results: list[Result],
                  shape_files: Sequence[Path] = ()) -> list[Result]:
    """``results`` without those of a rule that does not hold for the edition of their focus
    instance: of an edition's own rule shape (``shape_files``: the shapes in use) on an instance of
    another, of a 2002 rule the instance's edition has otherwise or lacks, and those that hold an
    instance of another edition than 2002 to a 2002 attribute its edition does not give its entity."""
    own_shape, not_for = edition_marks(shape_files)
    own, others = _editions(store, graph)
    if own == SHIPPED and not others and not own_shape:
        return results
    kept = []
    for r in results:
        edition = others.get(r.focus, own)
        if r.shape is not None and (own_shape.get(r.shape, edition) != edition
                                    or edition in not_for.get(r.shape, frozenset())):
            continue
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


def edition_notes(store: ox.Store, graph: str, shape_files: Sequence[Path]) -> list[str]:
    """What the report says when ``graph`` holds instances read in an edition other than 2002 and
    none of the shapes in use is a rule of that edition (a user's own set, ``--no-iso-shapes``,
    without ``shapes/edition_<edition>.ttl``): those instances were checked by the given shapes
    only, so a rule of their edition that differs from 2002 was not checked. Said, not left silent."""
    own_shape, _ = edition_marks(shape_files)
    covered = set(own_shape.values())
    own, others = _editions(store, graph)
    counts = Counter(others.values())
    out = []
    for edition in sorted(({own} | set(counts)) - {SHIPPED} - covered):
        read = f"{counts[edition]:,} instance(s) of" if edition != own else "the instances of"
        out.append(f"{graph}: {read} edition {edition} were checked by the given shapes only, not by that "
                   f"edition's own WHERE rules (shapes/edition_{edition}.ttl, part of the ISO 14649 shapes, is "
                   f"not among them)")
    return out
