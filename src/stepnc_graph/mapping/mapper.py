"""Map Part 21 instances to N-Triples lines, schema-driven.

An instance that fits the schema becomes a node typed with its entity class
(every partial entity's class for a complex instance) and one triple per set
value, in the representation of :mod:`stepnc_graph.vocabulary.typemap`. One that does not
fit -- unknown entity name, wrong parameter count, a value of the wrong type, a
reference to an instance the file does not define -- is kept as a
``p21:RawInstance`` holding its exact source text, with a diagnostic (one per
problem: every unresolved reference is reported), so nothing is lost and the
writer can put it back. An instance the lenient reader repaired also keeps the
repaired text, which is what the writer writes; one it could not read at all is
a ``p21:UnreadableInstance`` holding its text and the syntax error.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from stepnc_graph.mapping import ntriples as T
from stepnc_graph.mapping.editions import OtherInstance, unread_form
from stepnc_graph.mapping.plans import (
    P21_DERIVED,
    P21_EDITION,
    P21_EMPTY,
    P21_ENTITY_NAME,
    P21_ID,
    P21_LINE,
    P21_RAW,
    P21_RAW_TEXT,
    P21_REPAIRED_TEXT,
    P21_SECTION,
    P21_SYNTAX_ERROR,
    P21_UNREADABLE,
    P21_UNKNOWN,
    P21_UNSET,
    P21_VALUE,
    Encoding,
    EntityPlan,
    Plans,
    Slot,
)
from stepnc_graph.part21.diagnostics import Diagnostic
from stepnc_graph.part21.format import FormatError, format_instance
from stepnc_graph.part21.reader import Instance
from stepnc_graph.part21.values import DERIVED, UNSET, Binary, Enum, Name, Ref, Typed


class Mismatch(Exception):
    """A value that does not fit; ``code`` is the diagnostic code."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code
        self.message = message


def describe(value: Any) -> str:
    """A value as Part 21 would write it, for messages."""
    if value is UNSET or value is DERIVED:
        return repr(value)
    if isinstance(value, Ref):
        return f"#{int(value)}"
    if isinstance(value, Enum):
        return f".{value}."
    if isinstance(value, list):
        inner = ",".join(describe(v) for v in value[:4])
        return f"({inner}{',...' if len(value) > 4 else ''})"
    if isinstance(value, Typed):
        return f"{value.name}({describe(value.value)})"
    if isinstance(value, str):
        return repr(value)
    return str(value)


def _finite(value: float | int) -> float:
    """A REAL as a double; one no double can hold (``1E999``) does not fit the attribute."""
    try:
        number = float(value)
    except OverflowError:
        number = float("inf")
    if not math.isfinite(number):
        raise Mismatch("P21-VALUE-TYPE", f"the REAL {describe(value)} is out of the range of a double")
    return number


def _refs(inst: Instance) -> list[int]:
    """Every instance reference among the instance's parameters, nested ones included."""
    found: list[int] = []
    stack: list[Any] = list(inst.params) if inst.parts is None else [p for _, ps in inst.parts for p in ps]
    while stack:
        value = stack.pop()
        kind = type(value)
        if kind is Ref:
            found.append(int(value))
        elif kind is list:
            stack.extend(value)
        elif kind is Typed:
            stack.append(value.value)
    return found


@dataclass(frozen=True)
class DerivedTables:
    """What the mapper writes into a file's derived layer while it maps (:mod:`stepnc_graph.loading.derive`).

    The mapper already holds each instance's class and attribute values as
    N-Triples terms, so writing the class closure, the generic attribute
    values and the labels here costs a dictionary look-up per value -- where
    finding them again in the store took a SPARQL CONSTRUCT over the whole
    graph and a second parse of its result. ``superclasses``: class IRI ->
    the IRIs of its superclasses; ``generic``: attribute property IRI -> its
    generic property IRI; ``labels``: the its_id properties whose non-empty
    value is also an ``rdfs:label``. Values that are blank nodes (lists,
    typed values) are written to the store by :func:`~stepnc_graph.loading.derive.derive`:
    a blank node cannot be named in another graph's document. Their lines go to
    :attr:`InstanceMapper.derived_blank_lines` instead, the blank nodes named as
    in the program's lines, for a replacement to compare with the version in the
    store: the generic values that are blank nodes, and ``index`` (the IRI of
    ``sga:index``) on each cell of the lists that ``lists`` (attribute
    property IRIs) hold, nested lists included.
    """

    superclasses: dict[str, tuple[str, ...]]
    generic: dict[str, str]
    labels: frozenset[str]
    lists: frozenset[str] = frozenset()
    index: str = ""


def merge_tables(a: DerivedTables, b: DerivedTables) -> DerivedTables:
    """Tables that answer for the classes and properties of both (their IRIs never clash: editions
    share a term only where they share its meaning)."""
    return DerivedTables({**a.superclasses, **b.superclasses}, {**a.generic, **b.generic}, a.labels | b.labels,
                         a.lists | b.lists, a.index or b.index)


#: (entity name, parameter count) -> (edition, its plan, its derived tables, what the file's own
#: edition has under that name) for an instance that fits another edition; None when none fits
Fallback = Callable[[str, int], "tuple[str, EntityPlan, DerivedTables | None, str] | None"]


class InstanceMapper:
    """Turns instances of one file into N-Triples lines for one named graph.

    ``defined`` is the set of instance ids the file defines (for unresolved
    references); ``subject`` mints an instance's IRI from its id; ``section``,
    given for a file with several DATA sections, mints the IRI of a section
    from its 0-based index (each instance then records its section). With
    ``derived`` tables, the derived-layer lines of each mapped instance go to
    :attr:`derived_lines` (see :class:`DerivedTables`). With a ``positions``
    dict, each instance's line goes there under its #id instead of into
    ``p21:id``/``p21:line`` triples: for a throw-away graph that only the
    validator reads, which then reports positions from the dict (a sixth fewer
    triples to insert).
    """

    def __init__(self, plans: Plans, subject: Callable[[int], str], defined: set[int], filename: str,
                 source: str, section: Callable[[int], str] | None = None,
                 derived: DerivedTables | None = None, positions: dict[int, int] | None = None,
                 fallback: Fallback | None = None) -> None:
        self.plans = plans
        #: where an instance that does not fit ``plans`` may fit another edition (see :meth:`map`)
        self.fallback = fallback
        #: each instance read by :attr:`fallback`, for the load's report
        self.other_forms: list[OtherInstance] = []
        self.positions = positions
        self.derived = derived
        #: derived-layer lines of the instances mapped so far (the loader takes them away)
        self.derived_lines: list[str] = []
        #: derived-layer lines with the program's blank nodes (see DerivedTables)
        self.derived_blank_lines: list[str] = []
        self.section = section
        self.subject = subject
        self.defined = defined
        self.filename = filename
        self.source = source
        self.diagnostics: list[Diagnostic] = []
        self.raw_count = 0
        #: ids of instances the reader could not read (their text is kept)
        self.unreadable: set[int] = set()
        #: references made by raw instances: (#id, line, column, referenced ids), for the
        #: check against unreadable instances once the whole file is read
        self.raw_refs: list[tuple[int, int, int, list[int]]] = []
        self._bnode = 0
        #: whether every list mapped so far has a length within its type's bounds (which the
        #: mapper does not enforce: the shapes report it); lets validation skip those checks
        self.lists_within_bounds = True
        #: whether no mandatory attribute mapped so far was left unset ($) or derived (*)
        self.mandatory_values_set = True
        #: (declaring entity, its_id) -> the one instance IRI with that label, or
        #: None when several instances share it (then it identifies nothing).
        self.labels: dict[tuple[str, str], str | None] = {}
        #: whether a list mapped so far holds an unset member ($, written p21:unset)
        self.unset_members = False
        #: attribute properties whose lines (values, list cells) go to :attr:`held`, not the output
        self.hold: frozenset[str] = frozenset()
        #: the lines of :attr:`hold`'s attributes, of the instances mapped so far (see the loader)
        self.held: list[str] = []
        self._holding: list[str] = []  # those of the instance being mapped

    # -- values ----------------------------------------------------------------

    def _blank(self) -> str:
        self._bnode += 1
        return f"_:b{self._bnode}"

    def _ref(self, value: Ref) -> str:
        if int(value) not in self.defined:
            raise Mismatch("P21-UNRESOLVED-REF", f"#{int(value)} is not defined in the file")
        return f"<{self.subject(int(value))}>"

    def encode(self, enc: Encoding, value: Any, out: list[str]) -> str:
        """The RDF term for ``value``; list cells and typed wrappers go to ``out``."""
        kind = enc.kind
        vt = type(value)
        if kind == "real":
            if vt is float or vt is int:
                return T.double(_finite(value))
        elif kind == "entity":
            if vt is Ref:
                return self._ref(value)
        elif kind == "string":
            if vt is str:
                return T.string(value)
        elif kind == "integer":
            if vt is int:
                return T.integer(value)
        elif kind == "list":
            if vt is list:
                return self._list_value(enc, value, out, None)
        elif kind == "enum":
            if vt is Enum and value in enc.items:
                return f"<{enc.items[value]}>"
        elif kind == "boolean":
            if vt is Enum and value in ("T", "F"):
                return T.boolean(value == "T")
        elif kind == "logical":
            if vt is Enum and value in ("T", "F", "U"):
                return T.boolean(value == "T") if value != "U" else T.typed("UNKNOWN", P21_UNKNOWN)
        elif kind == "select":
            return self._select(enc, value, out)
        elif kind == "binary":
            if vt is Binary and value[:1] == "0" and len(value) % 2 == 1:
                return T.typed(value[1:].upper(), enc.datatype or "")
        elif kind == "any":
            raise Mismatch("P21-VALUE-TYPE", "generic types cannot be stored")
        raise self._mismatch(enc, value)

    @staticmethod
    def _mismatch(enc: Encoding, value: Any) -> Mismatch:
        if type(value) is Name:
            return Mismatch("P21-VALUE-TYPE", f"expected {enc.label}, found {value}, a value defined outside the "
                                              "file or a schema constant (edition 3), which cannot be typed here")
        return Mismatch("P21-VALUE-TYPE", f"expected {enc.label}, found {describe(value)}")

    def _list_value(self, enc: Encoding, value: list[Any], out: list[str], index: list[str] | None) -> str:
        n = len(value)
        if enc.lower is None or n < enc.lower or (enc.upper is not None and n > enc.upper):
            self.lists_within_bounds = False  # reported by the shapes; an expression bound: unknown
        return self._list(enc.element, value, out, index)  # type: ignore[arg-type]

    def _list(self, element: Encoding, values: list[Any], out: list[str], index: list[str] | None = None) -> str:
        """The head of a list of ``values``; with ``index``, the ``sga:index`` line of each cell
        (and of the cells of lists it holds) goes there (see DerivedTables)."""
        if not values:
            return T.RDF_NIL
        head = cell = self._blank()
        last = len(values) - 1
        nested = index is not None and element.kind == "list"
        for i, v in enumerate(values):
            if v is UNSET:
                term = P21_UNSET
                self.unset_members = True
            elif nested and type(v) is list:
                term = self._list_value(element, v, out, index)
            else:
                term = self.encode(element, v, out)
            if index is not None:
                index.append(f"{cell} <{self.derived.index}> {T.integer(i + 1)} .\n")  # type: ignore[union-attr]
            out.append(f"{cell} {T.RDF_FIRST} {term} .\n")
            nxt = T.RDF_NIL if i == last else self._blank()
            out.append(f"{cell} {T.RDF_REST} {nxt} .\n")
            cell = nxt
        return head

    def _select(self, enc: Encoding, value: Any, out: list[str]) -> str:
        vt = type(value)
        if vt is Ref and enc.accepts_refs:
            return self._ref(value)
        if vt is Enum and value in enc.items:
            return f"<{enc.items[value]}>"
        if vt is Typed and value.name in enc.typed:
            cls, inner = enc.typed[value.name]
            node = self._blank()
            out.append(f"{node} {T.RDF_TYPE} <{cls}> .\n")
            out.append(f"{node} {P21_VALUE} {self.encode(inner, value.value, out)} .\n")
            return node
        raise self._mismatch(enc, value)

    # -- instances ---------------------------------------------------------------

    def _slots(self, s: str, slots: tuple[Slot, ...], params: list[Any], out: list[str],
               derived: list[str] | None) -> None:
        on = self.derived is not None and derived is not None
        generic = self.derived.generic if on else {}  # type: ignore[union-attr]
        indexed = self.derived.lists if on else frozenset()  # type: ignore[union-attr]
        hold, holding = self.hold, self._holding
        for slot, value in zip(slots, params, strict=True):  # counts checked by _count
            if value is UNSET:
                if not slot.optional:
                    self.mandatory_values_set = False  # reported by the shapes (sh:minCount)
                continue
            if value is DERIVED:
                if not slot.optional:
                    self.mandatory_values_set = False
                out.append(f"{s} {P21_DERIVED} <{slot.prop}> .\n")
                continue
            dest = holding if slot.prop in hold else out
            try:
                if slot.repeated:
                    if type(value) is not list:
                        raise Mismatch("P21-VALUE-TYPE", f"expected a SET, found {describe(value)}")
                    if not value:
                        out.append(f"{s} {P21_EMPTY} <{slot.prop}> .\n")
                    members = [self.encode(slot.encoding, v, dest) for v in value]
                    if len(set(members)) != len(members):
                        # repeated triples would merge them: report instead of losing one
                        raise Mismatch("P21-VALUE-TYPE", f"a SET cannot hold a member twice: {describe(value)}")
                    dest.extend(f"{s} <{slot.prop}> {m} .\n" for m in members)
                    if slot.prop in generic:
                        self._generic(s, slot.prop, generic[slot.prop], members, derived)  # type: ignore[arg-type]
                else:
                    if type(value) is list and slot.encoding.kind == "list" and slot.prop in indexed:
                        term = self._list_value(slot.encoding, value, dest, self.derived_blank_lines)
                    else:
                        term = self.encode(slot.encoding, value, dest)
                    dest.append(f"{s} <{slot.prop}> {term} .\n")
                    if slot.prop in generic:
                        self._generic(s, slot.prop, generic[slot.prop], [term], derived)  # type: ignore[arg-type]
            except Mismatch as m:
                raise Mismatch(m.code, f"{slot.entity}.{slot.name} (parameter {slot.index + 1}): {m.message}") \
                    from None

    def _generic(self, s: str, prop: str, generic: str, members: list[str], derived: list[str]) -> None:
        """Generic values (and the label) of one attribute; those that are blank nodes apart: see
        DerivedTables."""
        for m in members:
            (derived if m[0] != "_" else self.derived_blank_lines).append(f"{s} <{generic}> {m} .\n")
        if prop in self.derived.labels:  # type: ignore[union-attr]
            derived.extend(f"{s} {T.RDFS_LABEL} {m} .\n" for m in members if m[0] == '"' and m[1] != '"')

    def _closure(self, s: str, cls: str, derived: list[str]) -> None:
        derived.extend(f"{s} {T.RDF_TYPE} <{c}> .\n" for c in self.derived.superclasses.get(cls, ()))  # type: ignore[union-attr]

    def _count(self, name: str, slots: tuple[Slot, ...], params: list[Any]) -> None:
        if len(params) != len(slots):
            raise Mismatch("P21-ARGUMENT-COUNT",
                           f"{name} takes {len(slots)} parameter(s) ({', '.join(s.name for s in slots)}), "
                           f"found {len(params)}")

    def _plan(self, name: str) -> EntityPlan:
        plan = self.plans.entities.get(name)
        if plan is None:
            raise Mismatch("P21-UNKNOWN-ENTITY", f"{name} is not an entity of the loaded schemas")
        return plan

    def map(self, inst: Instance, out: list[str]) -> None:
        """Append the instance's triples to ``out`` (raw form if it does not fit)."""
        s = f"<{self.subject(inst.id)}>"
        if inst.unreadable is not None:
            self._unreadable(inst, s, out)
            return
        lines: list[str] = []
        labels: list[tuple[str, Any]] = []
        blank_mark = len(self.derived_blank_lines)
        self._holding.clear()
        derived: list[str] | None = [] if self.derived is not None else None
        try:
            if inst.parts is None:
                try:
                    plan = self._plan(inst.name or "")
                    self._count(plan.name.upper(), plan.slots, inst.params)
                    self._simple(s, plan, inst.params, lines, derived, labels)
                except Mismatch as m:
                    plan = self._other_edition(inst, m, s, lines, derived, labels)
                if plan.abstract:
                    self._diagnose(inst, "P21-ABSTRACT", f"{plan.name} is ABSTRACT: instances belong to a subtype")
            else:
                for name, params in inst.parts:
                    plan = self._plan(name)
                    self._count(name, plan.own_slots, params)
                    lines.append(f"{s} {T.RDF_TYPE} <{plan.cls}> .\n")
                    if derived is not None:
                        self._closure(s, plan.cls, derived)
                    self._slots(s, plan.own_slots, params, lines, derived)
                    if plan.own_its_id is not None:
                        labels.append((plan.own_slots[plan.own_its_id].entity, params[plan.own_its_id]))
        except Mismatch as m:
            del self.derived_blank_lines[blank_mark:]  # the instance goes raw: none of its values
            # the rare path: report the mismatch and every reference the file does not define
            refs = sorted(set(_refs(inst)))
            if m.code != "P21-UNRESOLVED-REF":
                self._diagnose(inst, m.code, m.message)
            for target in refs:
                if target not in self.defined:
                    self._diagnose(inst, "P21-UNRESOLVED-REF", f"refers to #{target}, which is not defined in the file")
            self.raw_refs.append((inst.id, inst.line, inst.column, refs))
            self._raw(inst, s, out)
            return
        for scope, value in labels:
            self._label(scope, value, s)
        out.extend(lines)
        self.held += self._holding
        if derived:
            # a complex instance's partial classes share superclasses: each triple once
            self.derived_lines.extend(derived if inst.parts is None else dict.fromkeys(derived))
        self._source(inst, s, out)

    def _simple(self, s: str, plan: EntityPlan, params: list[Any], lines: list[str], derived: list[str] | None,
                labels: list[tuple[str, Any]]) -> None:
        """The triples of a simple instance that ``plan`` reads (parameter count checked)."""
        lines.append(f"{s} {T.RDF_TYPE} <{plan.cls}> .\n")
        if derived is not None:
            self._closure(s, plan.cls, derived)
        self._slots(s, plan.slots, params, lines, derived)
        if plan.its_id is not None:
            labels.append((plan.slots[plan.its_id].entity, params[plan.its_id]))

    def _other_edition(self, inst: Instance, first: Mismatch, s: str, lines: list[str], derived: list[str] | None,
                       labels: list[tuple[str, Any]]) -> EntityPlan:
        """An instance the file's edition does not know by name or parameter count, read in the
        edition it fits (:attr:`fallback`): its triples and ``p21:edition`` (so the writer writes it
        in that form again), recorded in :attr:`other_forms` -- evidence, not a diagnostic: the
        instance is correct in an edition stepnc-graph reads. ``first`` again when none fits."""
        found = None if self.fallback is None or first.code not in ("P21-UNKNOWN-ENTITY", "P21-ARGUMENT-COUNT") \
            else self.fallback(inst.name or "", len(inst.params))
        if found is None:
            known = unread_form(inst.name or "", len(inst.params)) if first.code == "P21-ARGUMENT-COUNT" else None
            raise first if known is None else Mismatch(first.code, f"{first.message}; {known}")
        edition, plan, tables, own = found
        del lines[:], labels[:], self._holding[:]
        if derived is not None:
            del derived[:]
        if tables is not None and self.derived is not None:
            self.derived = merge_tables(self.derived, tables)
        self._simple(s, plan, inst.params, lines, derived, labels)
        lines.append(f"{s} {P21_EDITION} {T.string(edition)} .\n")
        self.other_forms.append(OtherInstance(inst.id, inst.name or "", edition, inst.line,
                                              f"{len(plan.slots)} ({', '.join(sl.name for sl in plan.slots)})", own))
        return plan

    def _source(self, inst: Instance, s: str, out: list[str]) -> None:
        """Where the instance is in its file: #id, line, and (several DATA sections) its section."""
        if self.positions is not None:
            self.positions[inst.id] = inst.line
        else:
            out.append(f"{s} {P21_ID} {T.integer(inst.id)} .\n")
            out.append(f"{s} {P21_LINE} {T.integer(inst.line)} .\n")
        if self.section is not None:
            out.append(f"{s} {P21_SECTION} <{self.section(inst.section)}> .\n")

    def _label(self, scope: str, value: Any, s: str) -> None:
        """Remember an instance's its_id (a non-empty string) for its alias IRI."""
        if type(value) is str and value:
            key = (scope, value)
            self.labels[key] = None if key in self.labels else s[1:-1]

    def _raw(self, inst: Instance, s: str, out: list[str]) -> None:
        self.raw_count += 1
        names = "+".join(inst.names)
        out.append(f"{s} {T.RDF_TYPE} {P21_RAW} .\n")
        out.append(f"{s} {P21_ENTITY_NAME} {T.string(names)} .\n")
        out.append(f"{s} {P21_RAW_TEXT} {T.string(self.source[inst.start:inst.end])} .\n")
        if inst.repaired:
            try:
                out.append(f"{s} {P21_REPAIRED_TEXT} {T.string(format_instance(inst))} .\n")
            except FormatError:  # pragma: no cover - the reader reads no value format_instance cannot write
                pass
        self._source(inst, s, out)

    def _unreadable(self, inst: Instance, s: str, out: list[str]) -> None:
        """An instance with a syntax error: its text and the error, so nothing of the file is lost."""
        self.raw_count += 1
        self.unreadable.add(inst.id)
        out.append(f"{s} {T.RDF_TYPE} {P21_RAW} .\n")
        out.append(f"{s} {T.RDF_TYPE} {P21_UNREADABLE} .\n")
        if inst.name is not None:
            out.append(f"{s} {P21_ENTITY_NAME} {T.string(inst.name)} .\n")
        out.append(f"{s} {P21_RAW_TEXT} {T.string(self.source[inst.start:inst.end])} .\n")
        out.append(f"{s} {P21_SYNTAX_ERROR} {T.string(inst.unreadable or '')} .\n")
        self._source(inst, s, out)

    def _diagnose(self, inst: Instance, code: str, message: str) -> None:
        self.diagnostics.append(Diagnostic.make(code, self.filename, inst.line, inst.column, inst.id, message))
