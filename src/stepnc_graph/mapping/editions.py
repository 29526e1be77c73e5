"""Each edition of ISO 14649 mapped into one vocabulary: plans per edition, and a file's edition.

The shipped plans (:func:`~stepnc_graph.mapping.plans.iso14649_plans`) read the 2002 schemas.
A program written in another edition (``fdis2001``: ISO/FDIS 14649-10/-11 of 2001, see
``ontology/editions/README.md``) is read with that edition's plans, which this module builds from
the edition's own model so that queries meet one vocabulary:

* an entity of the edition that has a 2002 counterpart (the same name, or a name ISO changed:
  :data:`RENAMED`) takes, parameter by parameter, the 2002 property where the attribute means the
  same (same name or a renamed one, a value of the same kind); the class is the 2002 class when the
  name is the same, else the edition's own term ``stepnc:<2001 name>``, which the vocabulary states
  ``owl:equivalentClass`` (or, where an attribute differs in meaning, ``rdfs:subClassOf``) the 2002
  class (``ontology/editions/<edition>.ttl``), and which the derived layer closes over;
* an attribute that means something else (:data:`OWN_MEANING`) keeps the edition's term,
  ``stepnc:<2001 entity>.<attribute>``, with a generic ``attr:`` property of its own.

So a 2001 ``DRILL`` is written with exactly the triples a 2002 ``DRILL`` gets, a 2001
``CENTER_DRILL`` is a ``stepnc:center_drill`` that the derived layer also types ``stepnc:centerdrill``,
and the writer, given the same plans, writes each back in its own edition's form.

:func:`decide_edition` chooses a file's edition from what it holds (instances whose entity name only
one edition has) and what it says (FILE_SCHEMA, the FILE_NAME time stamp); ``--edition`` overrides.
"""

from __future__ import annotations

import dataclasses
import re
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any, NamedTuple

from stepnc_graph.core.naming import Naming
from stepnc_graph.mapping.plans import Encoding, EntityPlan, Plans, Slot, iso14649_plans

if TYPE_CHECKING:
    from stepnc_graph.part21.reader import Header

#: the edition the vocabulary, the shapes and the compiled model are built from
SHIPPED = "2002"
#: every edition a file can be read in, the shipped one first
EDITIONS = (SHIPPED, "fdis2001")
TITLES = {
    SHIPPED: "ISO 14649-10/-11/-111 as in the 2002 combined STEP-NC schema, with ISO/DIS 14649-12/-121:2003",
    "fdis2001": "ISO/FDIS 14649-10 V4 and ISO/FDIS 14649-11 V18 (2001-08-29)",
}
#: entity names an edition has where 2002 has another name for the same entity (2001 -> 2002)
RENAMED: dict[str, dict[str, str]] = {
    "fdis2001": {"center_drill": "centerdrill", "explicit": "explicit_strategy",
                 "milling_tool_body": "milling_machine_tool_body", "threading_tool": "milling_threading_tool",
                 "tool_dimension": "milling_tool_dimension"},
}
#: attributes an edition names otherwise with the same meaning: (entity, name) -> the 2002 name
RENAMED_ATTRIBUTES: dict[str, dict[tuple[str, str], str]] = {
    "fdis2001": {("three_axes_tilted_tool", "tool_direction"): "its_tool_direction",
                 ("workpiece_probing", "direction"): "its_direction"},
}
#: attributes of an edition whose meaning 2002 does not share, though they sit where a 2002
#: attribute sits: the 2001 ``tool_top_angle`` is not declared a half angle (2002 renamed it
#: ``tool_tip_half_angle``); a query asking for the half angle must not get it
OWN_MEANING: dict[str, frozenset[tuple[str, str]]] = {
    "fdis2001": frozenset({("tool_dimension", "tool_top_angle")}),
}
#: FILE_SCHEMA names only one edition's schemas have
_SCHEMA_EDITION = {"MILLING_TOOL_SCHEMA": SHIPPED, "TURNING_SCHEMA": SHIPPED, "TURNING_MACHINE_TOOL_SCHEMA": SHIPPED,
                   "COMBINED_SCHEMA": SHIPPED}


#: forms of entities that editions stepnc-graph cannot read have, by (entity, parameter count):
#: (the edition, its parameters, where it is recorded). Named in the diagnostic of an instance
#: in such a form, which no edition read here has (it stays a diagnostic, the instance raw).
#: ``cutting_component`` with 4: ISO 14649-10 as published (2004) dropped ``technological_data``
#: and renamed ``tool_offset_length``, as the merged AP238 ARM EXPRESS of 2006 (STEP Tools, IS
#: version, the published ISO 14649-10/-11/-12/-111/-121 merged) declares it, untagged by its
#: "ADDED BY 10303-238" and "RELAXED BY 10303-238" marks; ISO/FDIS 14649-11 Annex F's first example
#: program is written in it.
UNREAD_FORMS: dict[tuple[str, int], tuple[str, str, str]] = {
    ("cutting_component", 4): ("ISO 14649-10 as published (2004)",
                               "tool_functional_length, its_material, expected_tool_life, its_technology",
                               "the merged AP238 ARM EXPRESS of 2006"),
}


def unread_form(name: str, count: int) -> str | None:
    """What :data:`UNREAD_FORMS` says of ``name`` with ``count`` parameters, as a clause of a
    diagnostic's message; None when it knows no such form."""
    known = UNREAD_FORMS.get((name.lower(), count))
    if known is None:
        return None
    edition, params, source = known
    return (f"{count} parameters ({params}) is the form of {edition}, an edition stepnc-graph does not read "
            f"(recorded in {source}); kept raw")


def check_edition(edition: str) -> str:
    """``edition`` if it is one this module reads, else a ``ValueError`` that lists them."""
    if edition not in EDITIONS:
        raise ValueError(f"unknown edition {edition!r}; known: {', '.join(EDITIONS)}")
    return edition


# -- plans -------------------------------------------------------------------------------------


def _compatible(a: Encoding, b: Encoding, renamed: dict[str, str]) -> bool:
    """Whether the 2002 encoding ``b`` reads every value the edition's ``a`` reads, to the same
    RDF term (so the 2002 property can hold it and the writer writes it back the same)."""
    if a.kind != b.kind:
        return False
    if a.kind == "entity":
        return True  # a reference is a reference: the referenced instance carries its own class
    if a.kind in ("enum", "select"):
        items_ok = all(b.items.get(k) == v for k, v in a.items.items())
        typed_ok = all(k in b.typed and b.typed[k][0] == c for k, (c, _) in a.typed.items())
        return items_ok and typed_ok and (b.accepts_refs or not a.accepts_refs)
    if a.kind == "list":
        return a.element is not None and b.element is not None and _compatible(a.element, b.element, renamed)
    return True  # the same simple kind


def _shared_slots(edition: str, own: tuple[Slot, ...], base: tuple[Slot, ...]) -> tuple[Slot, ...]:
    """``own`` (the edition's slots of one entity), each replaced by the 2002 slot of the same
    attribute where it means the same (keeping the edition's position)."""
    renamed, attrs = RENAMED.get(edition, {}), RENAMED_ATTRIBUTES.get(edition, {})
    own_meaning = OWN_MEANING.get(edition, frozenset())
    by_name = {(renamed.get(s.entity, s.entity), s.name): s for s in base}
    out: list[Slot] = []
    for slot in own:
        entity = renamed.get(slot.entity, slot.entity)
        key = (entity, attrs.get((slot.entity, slot.name), slot.name))
        match = by_name.get(key)
        if match is None:  # declared by another supertype in 2002: match by name alone
            named = [s for s in base if s.name == key[1]]
            match = named[0] if len(named) == 1 else None
        if (match is not None and (slot.entity, slot.name) not in own_meaning
                and match.repeated == slot.repeated and _compatible(slot.encoding, match.encoding, renamed)):
            out.append(dataclasses.replace(match, index=slot.index))
        else:
            out.append(slot)
    return tuple(out)


def _edition_plan(edition: str, own: EntityPlan, base: Plans) -> EntityPlan:
    renamed = RENAMED.get(edition, {})
    counterpart = base.entities.get(renamed.get(own.name, own.name).upper())
    if counterpart is None:
        return own
    slots = _shared_slots(edition, own.slots, counterpart.slots)
    own_slots = _shared_slots(edition, own.own_slots, counterpart.own_slots + counterpart.slots)
    cls = counterpart.cls if own.name == counterpart.name else own.cls
    return dataclasses.replace(own, cls=cls, slots=slots, own_slots=own_slots)


def build_edition_plans(edition: str, base: Plans, own: Plans) -> Plans:
    """The plans of ``edition`` from the shipped plans ``base`` and the plans of the edition's own
    model ``own`` (its IRIs minted in the shared namespace): exactly the edition's entities, each
    in the shared vocabulary (see the module doc)."""
    plans = Plans.__new__(Plans)
    plans.model = own.model
    plans.n = base.n
    plans._enc = {**own._enc, **base._enc}
    plans.entities = {key: _edition_plan(edition, p, base) for key, p in own.entities.items()}
    plans._index()
    return plans


#: where ``stepnc-graph ontology build`` writes an edition's compiled model and plans (beside its
#: catalogue directory, whose digest covers every file in it)
COMPILED = "editions/{edition}.compiled-model.json"


def own_plans(edition: str, naming: Naming) -> Plans:
    """The plans of the edition's own model: from its compiled model when that is fresh, else built
    from its EXPRESS (a few seconds) with a :class:`~stepnc_graph.schema.cache.CompiledModelWarning`."""
    import warnings

    from stepnc_graph.core.resources import ontology_dir
    from stepnc_graph.schema import cache
    from stepnc_graph.schema.catalog import edition_directory, load_edition_model

    directory = edition_directory(edition)
    path = ontology_dir() / COMPILED.format(edition=edition)
    try:
        text = path.read_text(encoding="utf-8")
        compiled = cache.loads(text, directory, cache.express_digest(directory))
        if compiled.plans is not None:
            return Plans.restore(compiled.model, naming, compiled.plans)
        reason = "it holds no plans"
    except OSError as exc:
        reason = f"it cannot be read ({exc.strerror or exc})"
    except cache.StaleCache as exc:
        reason = str(exc)
    warnings.warn(f"{path} is not used: {reason}. Building the {edition} model from its EXPRESS instead; "
                  f"`stepnc-graph ontology build` refreshes the file.", cache.CompiledModelWarning, stacklevel=2)
    return Plans(load_edition_model(edition)[1], naming)


@lru_cache(maxsize=len(EDITIONS))
def edition_plans(edition: str) -> Plans:
    """The plans that read and write programs of ``edition``: exactly its entities, in the shared
    vocabulary (see the module doc). The shipped edition's are :func:`iso14649_plans`."""
    base = iso14649_plans()
    if check_edition(edition) == SHIPPED:
        return base
    return build_edition_plans(edition, base, own_plans(edition, base.n))


@dataclass(frozen=True)
class EditionTerm:
    """A class or property an edition has and 2002 does not: its IRI, how it relates to the 2002
    vocabulary (``equivalent``, ``subclass`` or ``own``) and the 2002 term it relates to."""

    iri: str
    relation: str
    shipped: str | None
    plan: EntityPlan | None = None
    slot: Slot | None = None


def edition_terms(edition: str, plans: Plans | None = None, base: Plans | None = None) -> list[EditionTerm]:
    """The edition's own classes and properties (what ``ontology/edition_<edition>.ttl`` declares),
    from its ``plans`` against the shipped ``base`` (default: the loaded ones)."""
    base = base or iso14649_plans()
    plans = plans or edition_plans(edition)
    renamed = RENAMED.get(edition, {})
    shipped = {s.prop for p in base.entities.values() for s in p.slots + p.own_slots}
    out: list[EditionTerm] = []
    props: dict[str, EditionTerm] = {}
    for plan in sorted(plans.entities.values(), key=lambda p: p.name):
        if plan.cls not in base.by_class:
            target = base.entities.get(renamed.get(plan.name, plan.name).upper())
            differs = any((plan.name, s.name) in OWN_MEANING.get(edition, frozenset()) for s in plan.own_slots)
            out.append(EditionTerm(plan.cls, "subclass" if differs else "equivalent",
                                   target.cls if target else None, plan=plan))
        for slot in plan.own_slots:
            if slot.prop not in shipped:
                props.setdefault(slot.prop, EditionTerm(slot.prop, "own", None, plan=plan, slot=slot))
    return out + sorted(props.values(), key=lambda t: t.iri)


def counterpart_classes(edition: str, plans: Plans, base: Plans) -> list[tuple[str, str]]:
    """(edition class, its 2002 counterpart) for each class of ``edition`` the 2002 vocabulary does
    not have: the subclass pairs the shapes' class hierarchy adds (``shapes/support.ttl``)."""
    return sorted({(t.iri, t.shipped) for t in edition_terms(edition, plans, base)
                   if t.slot is None and t.shipped is not None})


def edition_ontology_iri(edition: str, naming: Naming) -> str:
    return f"{naming.ontology_base}edition/{edition}"


def edition_turtle(edition: str, plans: Plans, base: Plans) -> str:
    """``ontology/edition_<edition>.ttl``: the edition's own classes (``owl:equivalentClass`` or
    ``rdfs:subClassOf`` their 2002 counterpart) and properties (with their generic ``attr:``
    property), so OWL tools and queries over the vocabulary graph see the bridge the derived layer
    uses. Written as text in a fixed order (byte-stable, checked by ``ontology build --check``)."""
    from stepnc_graph.core.naming import ATTRIBUTE_NS, P21_NS, generic_attribute_iri

    ns = base.n.namespace
    onto = edition_ontology_iri(edition, base.n)

    def term(iri: str) -> str:
        for prefix, space in (("stepnc", ns), ("attr", ATTRIBUTE_NS)):
            if iri.startswith(space):
                return f"{prefix}:{iri[len(space):]}"
        return f"<{iri}>"

    def text(value: str) -> str:
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'

    lines = [f"PREFIX {p}: <{i}>" for p, i in (
        ("attr", ATTRIBUTE_NS), ("owl", "http://www.w3.org/2002/07/owl#"), ("p21", P21_NS),
        ("rdfs", "http://www.w3.org/2000/01/rdf-schema#"), ("stepnc", ns),
        ("xsd", "http://www.w3.org/2001/XMLSchema#"))]
    about = (f"The terms of {TITLES[edition]} that the 2002 vocabulary does not have, and how they relate to it "
             "(see ontology/README.md, Editions).")
    lines += ["", f"<{onto}>", "    a owl:Ontology ;", f"    rdfs:label {text('ISO 14649 edition ' + edition)} ;",
              f"    rdfs:comment {text(about)} ;",
              f"    owl:imports <{base.n.ontology_base}milling_tool_schema>, <{base.n.ontology_base}milling_schema>, "
              f"<{base.n.ontology_base}machining_schema>, <{ATTRIBUTE_NS[:-1]}> ;", "."]
    generics: dict[str, str] = {}
    for t in edition_terms(edition, plans, base):
        lines.append("")
        if t.slot is None:
            assert t.plan is not None
            relation = "owl:equivalentClass" if t.relation == "equivalent" else "rdfs:subClassOf"
            said = ("the same entity under its 2002 name" if t.relation == "equivalent" else
                    "a 2002 entity whose attributes it shares except where the meaning differs, which keep "
                    "this edition's terms")
            comment = f"{t.plan.name} of {TITLES[edition]}: {said}."
            lines += [term(t.iri), "    a owl:Class ;", f"    rdfs:label {text(t.plan.name)} ;",
                      f"    rdfs:comment {text(comment)} ;",
                      *([f"    {relation} {term(t.shipped)} ;"] if t.shipped else []),
                      f"    rdfs:isDefinedBy <{onto}> ;", "."]
            continue
        slot = t.slot
        literal = slot.encoding.kind not in ("entity", "select", "list") and slot.encoding.datatype is not None
        kind = "owl:DatatypeProperty" if literal else "owl:ObjectProperty"
        generic = generic_attribute_iri(slot.name)
        generics.setdefault(generic, kind)
        lines += [term(t.iri), f"    a {kind} ;", f"    rdfs:label {text(slot.name)} ;",
                  f"    rdfs:comment {text(slot.entity + '.' + slot.name + ' of ' + TITLES[edition])} ;",
                  f"    rdfs:domain {term(ns + slot.entity)} ;",
                  *([f"    rdfs:range <{slot.encoding.datatype}> ;"] if literal else []),
                  f"    rdfs:subPropertyOf {term(generic)} ;", f"    rdfs:isDefinedBy <{onto}> ;", "."]
    known = _generic_kinds()
    for generic, kind in sorted(generics.items()):
        if generic not in known:
            lines += ["", term(generic), f"    a {kind} ;", f"    rdfs:label {text(generic.rsplit('#', 1)[1])} ;",
                      f"    rdfs:isDefinedBy <{onto}> ;", "."]
    return "\n".join(lines) + "\n"


def _generic_kinds() -> frozenset[str]:
    """The generic ``attr:`` properties the shipped ``generic.ttl`` declares."""
    from stepnc_graph.core.resources import ontology_dir

    path = ontology_dir() / "generic.ttl"
    names = re.findall(r"(?m)^attr:([A-Za-z0-9_.]+)$", path.read_text(encoding="utf-8")) if path.exists() else []
    from stepnc_graph.core.naming import ATTRIBUTE_NS

    return frozenset(ATTRIBUTE_NS + n for n in names)


# -- which edition a file is written in --------------------------------------------------------


@dataclass(frozen=True)
class EditionChoice:
    """The edition a file is read in, how it was chosen (``option``, ``content``, ``header`` or
    ``default``) and the evidence, one sentence each."""

    edition: str
    chosen_by: str
    evidence: tuple[str, ...]

    def asdict(self) -> dict[str, object]:
        return {"edition": self.edition, "title": TITLES[self.edition], "chosen_by": self.chosen_by,
                "evidence": list(self.evidence)}


@dataclass(frozen=True)
class OtherForm:
    """The instances of one entity that the file's edition cannot read (unknown name, another
    parameter count) and ``edition`` reads exactly: read in ``edition`` (``p21:edition`` on each).
    Evidence of what a file holds, not a problem: a file that mixes editions gets a diagnostic
    only for an instance no edition reads (issue 29). ``form`` is the edition's parameter list,
    ``file_has`` what the file's edition has under the name."""

    entity: str
    edition: str
    ids: tuple[int, ...]
    lines: tuple[int, ...]
    form: str
    file_has: str

    def asdict(self) -> dict[str, object]:
        return {"entity": self.entity, "edition": self.edition, "ids": [f"#{i}" for i in self.ids],
                "lines": list(self.lines), "form": self.form, "file_edition_has": self.file_has}


#: how many #ids of one entity a sentence of :func:`other_form_sentences` names
_NAMED_IDS = 10


class OtherInstance(NamedTuple):
    """One instance read in another edition than the file's (the mapper's record of it): its
    #id, entity name, that edition, its line, that edition's parameters and what the file's
    edition has under the name."""

    id: int
    name: str
    edition: str
    line: int
    form: str
    file_has: str


def group_other_forms(rows: list[OtherInstance]) -> tuple[OtherForm, ...]:
    """Per entity and edition, in file order: the :class:`OtherForm` of ``rows``, one per instance."""
    groups: dict[tuple[str, str], list[OtherInstance]] = {}
    for row in sorted(rows):
        groups.setdefault((row.name.upper(), row.edition), []).append(row)
    return tuple(OtherForm(entity, edition, tuple(r.id for r in rs), tuple(r.line for r in rs), rs[0].form,
                           rs[0].file_has) for (entity, edition), rs in groups.items())


def other_form_sentences(forms: tuple[OtherForm, ...]) -> list[str]:
    """One sentence per edition: ``2 instance(s) in the 2002 form: BORING_TOOL #244, #268`` (at
    most :data:`_NAMED_IDS` #ids named per entity; the load result lists them all)."""
    by_edition: dict[str, list[OtherForm]] = {}
    for f in forms:
        by_edition.setdefault(f.edition, []).append(f)
    out = []
    for edition, group in by_edition.items():
        named = []
        for f in group:
            ids = ", ".join(f"#{i}" for i in f.ids[:_NAMED_IDS])
            more = f" and {len(f.ids) - _NAMED_IDS:,} more" if len(f.ids) > _NAMED_IDS else ""
            named.append(f"{f.entity} {ids}{more}")
        out.append(f"{sum(len(f.ids) for f in group):,} instance(s) in the {edition} form: {'; '.join(named)}")
    return out


@lru_cache(maxsize=1)
def _table() -> dict[str, Any]:
    """``ontology/editions/editions.json``: per entity, its parameters in each edition."""
    from stepnc_graph.core.resources import express_dir
    from stepnc_graph.schema.editions import TABLE_FILE, read_table

    try:
        return read_table((express_dir().parent / TABLE_FILE).read_text(encoding="utf-8"))
    except OSError:  # a data directory without the table: the shipped edition is the only one known
        return {"editions": {SHIPPED: {}}, "only_in": {}, "entities": {}}


def other_fit(edition: str, name: str, count: int) -> str | None:
    """The first edition other than ``edition`` whose ``name`` takes ``count`` parameters (looked up
    in the editions' table, so no other edition's plans are built for an entity none has)."""
    from stepnc_graph.schema.editions import fitting_editions

    fits = fitting_editions(_table(), name, count)
    return next((e for e in EDITIONS if e != edition and e in fits), None)


@lru_cache(maxsize=1)
def _distinctive() -> tuple[dict[str, str], re.Pattern[str]]:
    """Entity name (upper case) -> the one edition that has it, among the entities some edition
    lacks; and a pattern that finds instances of them in Part 21 text."""
    table = _table()
    only = {name.upper(): edition for edition, names in table["only_in"].items() for name in names}
    alternation = "|".join(sorted(only, key=len, reverse=True)) or "(?!)"  # none: a pattern that never matches
    return only, re.compile(rf"#\d+\s*=\s*({alternation})\s*\(")


def _distinctive_names(text: str) -> Iterator[str]:
    r"""The names (upper case) of the instances of ``text`` whose entity only one edition has: an
    ``#id=NAME(`` at the start of the text or after ``;``, ``)`` or white space, in any case. The
    pattern opens with the literal ``#`` and reads upper-cased text, and the character before is
    tested here: a leading ``(?:^|[;\s)])`` or case-blind matching made the regex try every
    offset (0.25 CPU-s for 6 MB, now 0.06)."""
    _, pattern = _distinctive()
    upper = text.upper() if text.isascii() else None  # elsewhere upper() may change lengths or letters
    if upper is None:
        return (m.group(1).upper() for m in re.finditer(rf"(?<![^;\s)])(?:{pattern.pattern})", text, re.IGNORECASE))
    return (m.group(1) for m in pattern.finditer(upper)
            if m.start() == 0 or upper[m.start() - 1] in ";)" or upper[m.start() - 1].isspace())


def decide_edition(text: str, header: Header, forced: str | None = None) -> EditionChoice:
    """The edition to read ``text`` in, in this order: ``forced`` (``--edition``); the edition of a
    schema FILE_SCHEMA names that only one edition has (a file that says ``TURNING_SCHEMA`` is no
    2001 file, whatever entity names it misuses); the edition more instances' entity names belong to
    alone; the FILE_NAME time stamp (before 2002: not the 2002 edition); else the shipped edition.
    The evidence lists everything found, whichever decided."""
    only, _ = _distinctive()
    counts: Counter[str] = Counter()
    names: dict[str, Counter[str]] = {}
    for name in _distinctive_names(text):
        counts[only[name]] += 1
        names.setdefault(only[name], Counter())[name] += 1
    evidence = [f"{n} instance(s) of entities only {_label(e)} has "
                f"({', '.join(f'{k} x{v}' for k, v in sorted(names[e].items()))})" for e, n in counts.most_common()]
    schemas, dated = _schema_evidence(header), _date_evidence(header)
    evidence += [sentence for _, sentence in schemas + dated]
    if forced is not None:
        return EditionChoice(check_edition(forced), "option", (f"--edition {forced}", *evidence))
    said = {edition for edition, _ in schemas}
    if len(said) == 1:
        return EditionChoice(said.pop(), "header", tuple(evidence))
    ranked = counts.most_common()
    if ranked and (len(ranked) == 1 or ranked[0][1] > ranked[1][1]):
        return EditionChoice(ranked[0][0], "content", tuple(evidence))
    if dated:
        return EditionChoice(dated[0][0], "header", tuple(evidence))
    return EditionChoice(SHIPPED, "default", (*evidence, f"nothing tells the editions apart: read as {SHIPPED}"))


def _label(edition: str) -> str:
    return "the 2002 edition" if edition == SHIPPED else f"edition {edition}"


def _schema_evidence(header: Header) -> list[tuple[str, str]]:
    """FILE_SCHEMA names that only one edition's schemas have, with that edition."""
    return [(edition, f"FILE_SCHEMA names {schema}, a schema of {_label(edition)} only")
            for schema in header.schemas if (edition := _SCHEMA_EDITION.get(schema.upper())) is not None]


def _date_evidence(header: Header) -> list[tuple[str, str]]:
    """The FILE_NAME time stamp, when it is before 2002: the 2002 edition did not exist yet."""
    name = header.entities.get("FILE_NAME") or []
    stamp = name[1] if len(name) > 1 and isinstance(name[1], str) else ""
    year = re.search(r"(?<!\d)(19\d\d|20\d\d)(?!\d)", stamp) or re.search(r"-(\d\d)$", stamp.strip())
    if year is None:
        return []
    y = int(year.group(1)) if len(year.group(1)) == 4 else 2000 + int(year.group(1))
    return [("fdis2001", f"FILE_NAME time stamp {stamp!r} is before 2002")] if y < 2002 else []
