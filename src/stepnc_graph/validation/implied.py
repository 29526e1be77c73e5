"""Checks that the Part 21 mapping already guarantees, so a program it just wrote can skip them.

The loader's mapper (:mod:`stepnc_graph.mapping.mapper`) writes an attribute's
value only in the form of the attribute's type: one triple for a single-valued
attribute, an ``xsd:double`` for a REAL, an ``xsd:string`` for a STRING, list
members in the form of the member type; a value that does not fit makes the
whole instance a raw one (reported by the loader). So on a program graph the
mapper wrote, some generated constraints cannot fail (ISO 10303-11 types, as
SHACL shapes by :mod:`stepnc_graph.generators.shacl`):

* ``sh:maxCount`` n >= 1 on a single-valued attribute (not a SET);
* ``sh:datatype`` on an attribute of a simple type whose form is that datatype;
* ``sh:node`` of a list-members shape (only ``sh:datatype`` on
  ``rdf:rest*/rdf:first``) on a LIST of such a simple type -- unless a list
  holds an unset member (``$``, written ``p21:unset``), which the validator
  asks once per graph (:data:`NO_UNSET_MEMBERS`);
* ``sh:node`` of a list-length shape (``ListMax3``: no value at
  ``rdf:rest/rdf:rest/rdf:rest/rdf:first``) that the attribute's declared
  bounds imply -- when the mapper saw every list of the file within its
  bounds (it counts them, :attr:`~stepnc_graph.loading.loader.LoadResult.lists_within_bounds`;
  it does not refuse them: the shapes report them) (:data:`LIST_BOUNDS`);
* ``sh:minCount 1`` on a mandatory single-valued attribute -- when the
  mapper saw no ``$`` or ``*`` for a mandatory attribute in the file
  (:attr:`~stepnc_graph.loading.loader.LoadResult.mandatory_values_set`) (:data:`MANDATORY_SET`).

At 100k instances these are about half the validator's time (most of it the
coordinates of the cartesian points). They are skipped only for graphs that
``validate`` loaded itself from Part 21 text, never for a store (whose graphs
another writer may have changed) or a JSON-LD file. Cross-checked: a test runs
every skipped check on every fixture, damaged ones included, and requires that
none finds anything (``tests/test_validate.py``).
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict
from collections.abc import Sequence

from stepnc_graph.mapping import ntriples as T
from stepnc_graph.mapping.plans import Plans, Slot
from stepnc_graph.validation.engine import Check
from stepnc_graph.validation.shapes import RDF_FIRST, RDF_REST, RDF_TYPE, RDFS, ShapesGraph, literal_text, sh

RDFS_COMMENT = f"<{RDFS}comment>"
#: the check cannot fail on a graph the mapper wrote
ALWAYS = "always"
#: ... nor when no list of that graph holds an unset member
NO_UNSET_MEMBERS = "no-unset-members"
#: ... nor when the mapper saw every list within its type's bounds
LIST_BOUNDS = "list-bounds"
#: ... nor when the mapper saw a value for every mandatory attribute
MANDATORY_SET = "mandatory-set"
#: the datatype of the literal the mapper writes for each simple encoding
KIND_DATATYPE = {"real": T.T_DOUBLE, "string": f"<{T.XSD}string>", "integer": T.T_INTEGER, "boolean": T.T_BOOLEAN}


def mark(checks: Sequence[Check], graph: ShapesGraph, plans: Plans) -> list[Check]:
    """``checks`` with :attr:`Check.implied` set where the mapping guarantees them."""
    slots = _slots(plans)
    return [dataclasses.replace(c, implied=_implied(c, graph, slots.get(c.path_term or "", [])))
            if c.path_term in slots else c for c in checks]


_SLOTS: dict[int, dict[str, list[Slot]]] = {}


def _slots(plans: Plans) -> dict[str, list[Slot]]:
    """The mapping's slots by attribute property (``<iri>``), built once per set of plans: shapes
    compiled in a process (an organisation's own, the W3C suite's) reuse it."""
    found = _SLOTS.get(id(plans))
    if found is None:
        index: dict[str, list[Slot]] = defaultdict(list)
        for plan in plans.entities.values():
            for slot in (*plan.slots, *plan.own_slots):
                index[f"<{slot.prop}>"].append(slot)
        found = _SLOTS[id(plans)] = dict(index)
    return found


def _implied(check: Check, graph: ShapesGraph, slots: list[Slot]) -> str | None:
    if not slots or check.argument is None:
        return None
    if check.constraint == "maxCount":
        return ALWAYS if int(literal_text(check.argument)) >= 1 and not any(s.repeated for s in slots) else None
    if check.constraint == "minCount":
        one = int(literal_text(check.argument)) == 1
        return MANDATORY_SET if one and not any(s.optional or s.repeated or s.derived for s in slots) else None
    if check.constraint == "datatype":
        return ALWAYS if all(KIND_DATATYPE.get(s.encoding.kind) == check.argument for s in slots) else None
    if check.constraint == "node":
        if not all(s.encoding.kind == "list" and not s.repeated and s.encoding.element is not None for s in slots):
            return None
        member = _members_datatype(graph, check.argument)
        if member is not None:
            fits = all(KIND_DATATYPE.get(s.encoding.element.kind) == member for s in slots)  # type: ignore[union-attr]
            return NO_UNSET_MEMBERS if fits else None
        bound = _length_bound(graph, check.argument)
        if bound is not None:
            kind, n = bound
            held = [s.encoding.upper if kind == "max" else s.encoding.lower for s in slots]
            fits = all(h is not None and (h <= n if kind == "max" else h >= n) for h in held)
            return LIST_BOUNDS if fits else None
    return None


def _length_bound(graph: ShapesGraph, shape: str) -> tuple[str, int] | None:
    """("max", n) for a shape allowing lists of at most n members (no value at rest{n}/first), ("min", n)
    for at least n (a value at rest{n-1}/first); None for any other shape."""
    props = graph.objects(shape, sh("property"))
    if len(props) != 1 or set(graph.predicates(shape)) - {RDF_TYPE, sh("property"), RDFS_COMMENT}:
        return None
    member = props[0]
    counts = set(graph.predicates(member)) - {RDF_TYPE, sh("path")}
    path = graph.value(member, sh("path"))
    if path is None or len(counts) != 1:
        return None
    steps = graph.items(path) if path.startswith("_:") else [path]
    if steps[-1] != RDF_FIRST or any(step != RDF_REST for step in steps[:-1]):
        return None
    rests = len(steps) - 1
    if counts == {sh("maxCount")} and literal_text(graph.value(member, sh("maxCount")) or "") == "0":
        return "max", rests
    if counts == {sh("minCount")} and literal_text(graph.value(member, sh("minCount")) or "") == "1":
        return "min", rests + 1
    return None


def _members_datatype(graph: ShapesGraph, shape: str) -> str | None:
    """The datatype of a list-members shape: one property shape on ``rdf:rest*/rdf:first`` with
    ``sh:datatype`` only; None for any other shape."""
    props = graph.objects(shape, sh("property"))
    if len(props) != 1 or set(graph.predicates(shape)) - {RDF_TYPE, sh("property")}:
        return None
    member = props[0]
    if set(graph.predicates(member)) - {RDF_TYPE, sh("path"), sh("datatype")}:
        return None
    path, datatype = graph.value(member, sh("path")), graph.value(member, sh("datatype"))
    if path is None or datatype is None or not path.startswith("_:"):
        return None
    steps = graph.items(path)
    if len(steps) != 2 or steps[1] != RDF_FIRST:
        return None
    zero_or_more = graph.objects(steps[0], sh("zeroOrMorePath"))
    return datatype if zero_or_more == [RDF_REST] and len(graph.predicates(steps[0])) == 1 else None
