"""Write a loaded graph back as a Part 21 file.

The inverse of :mod:`stepnc_graph.mapping.mapper`, driven by the same plans:
each instance node becomes ``#id=NAME(...)`` with its parameters in Part 21
order -- missing values ``$``, ``p21:derivedValue`` ``*``, ``rdf:List`` in
order, SET members in ascending ``#id`` order (sets have no order; this keeps
a set written in order unchanged) -- and each ``p21:RawInstance`` its source
text, verbatim, or the text the lenient reader repaired (``p21:repairedText``).
What the reader could not read (``p21:UnreadableInstance``, a later definition
of an ``#id``, ``p21:unreadableText`` at the end of its DATA section) is written
as a comment holding its text: the output always
parses strictly, and nothing of the original is lost. Instances keep their
``p21:id``; nodes without one (added by SPARQL Update, say) get fresh ids above
the largest.
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Iterable
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.mapping.plans import (
    P21_DERIVED,
    P21_EMPTY,
    P21_ID,
    P21_DUPLICATE,
    P21_RAW,
    P21_RAW_TEXT,
    P21_REPAIRED_TEXT,
    P21_SECTION,
    P21_UNREADABLE,
    P21_UNREADABLE_TEXT,
    P21_UNKNOWN,
    P21_UNSET,
    P21_VALUE,
    Encoding,
    Plans,
    Slot,
)
from stepnc_graph.mapping.ntriples import RDF, RDF_TYPE, XSD
from stepnc_graph.core.naming import P21_NS
from stepnc_graph.part21.diagnostics import Part21SyntaxError
from stepnc_graph.part21.format import FormatError
from stepnc_graph.part21.format import format_real as part21_real
from stepnc_graph.part21.reader import read_instance, read_text
from stepnc_graph.part21.strings import encode

_TRAILING_ID = re.compile(r"i([0-9]+)$")
_DEFAULT_HEADER = ("HEADER;\nFILE_DESCRIPTION(('stepnc-graph export'),'2;1');\n"
                   "FILE_NAME('','',(''),(''),'stepnc-graph','stepnc-graph','');\n"
                   "FILE_SCHEMA(({schemas}));\nENDSEC;")


class WriteError(StepncGraphError, ValueError):
    """A graph that cannot be written as Part 21 (a value that fits no parameter)."""


def _key(term: Any) -> str:
    return f"_:{term.value}" if isinstance(term, ox.BlankNode) else f"<{term.value}>"


def format_real(value: float) -> str:
    """A Part 21 REAL: always with a decimal point (``1.``, ``2.5E-03``)."""
    try:
        return part21_real(value)
    except FormatError as e:
        raise WriteError(str(e)) from None


def comment(text: str) -> str:
    """``text`` as a Part 21 comment (a ``*/`` inside is broken up so the comment ends where it should)."""
    return "/* " + text.replace("*/", "* /") + " */"


def _set_order(text: str) -> tuple[int, int, str]:
    """Sort key of a written SET member: instance references by #id, then other values by text."""
    return (0, int(text[1:]), "") if text[:1] == "#" and text[1:].isdigit() else (1, 0, text)


def _edition_plans(edition: str) -> Plans:
    """The plans that write instances of ``edition`` (a graph's or an instance's ``p21:edition``)."""
    from stepnc_graph.mapping.editions import EDITIONS, edition_plans

    if edition not in EDITIONS:
        raise WriteError(f"p21:edition {edition!r} is not an edition stepnc-graph reads ({', '.join(EDITIONS)})")
    return edition_plans(edition)


class Part21Writer:
    """Serialises the triples of one graph (given as quads) to Part 21 text."""

    def __init__(self, plans: Plans) -> None:
        self.plans = plans
        self.enum_items = plans.item_names
        self.typed_names = plans.typed_names
        #: edition name -> a writer of that edition's plans sharing this one's graph (``p21:edition``)
        self._editions: dict[str, Part21Writer] = {}

    def _in_edition(self, edition: str | None) -> "Part21Writer":
        """The writer for instances of ``edition`` (this one for None): the plans of
        :func:`stepnc_graph.mapping.editions.edition_plans`, reading the same graph."""
        if edition is None:
            return self
        if edition not in self._editions:
            other = Part21Writer(_edition_plans(edition))
            other.props, other.ids, other._editions = self.props, self.ids, self._editions
            self._editions[edition] = other
        return self._editions[edition]

    # -- reading the graph ----------------------------------------------------------

    def write(self, quads: Iterable[ox.Quad] | Iterable[ox.Triple], graph: str | None = None) -> str:
        props: dict[str, dict[str, list[Any]]] = defaultdict(lambda: defaultdict(list))
        for q in quads:
            props[_key(q.subject)][f"<{q.predicate.value}>"].append(q.object)
        self.props = props
        meta = f"<{graph}>"

        def text(term: str) -> str | None:
            return self._first(meta, term) if graph is not None else None

        self.ids: dict[str, int] = {}
        edition = self._first(meta, "edition") if graph is not None else None
        if edition is not None:  # a program read in another edition: its instances are written in it
            plans = _edition_plans(edition)
            self.plans, self.enum_items, self.typed_names = plans, plans.item_names, plans.typed_names
        instances = self._instances(props)
        self.ids.update({key: i for i, key in instances})
        schemas = self._schemas(props, graph)
        header = text("repairedHeaderText") or text("headerText") or _DEFAULT_HEADER.format(schemas=",".join(encode(s) for s in schemas))
        # edition 3: ANCHOR and REFERENCE sections verbatim (ids are kept, so they still hold)
        extra = "".join(f"{t}\n" for t in (text("anchorSectionText"), text("referenceSectionText")) if t)
        texts = self._unreadable_texts(meta) if graph is not None else []
        sections = self._sections(instances, texts)
        _check_frame(graph, header, extra, [opener for opener, _ in sections])
        body = "".join(f"{opener}\n" + "\n".join(parts) + "\nENDSEC;\n" for opener, parts in sections)
        return "ISO-10303-21;\n" + header + "\n" + extra + body + "END-ISO-10303-21;\n"

    def _sections(self, instances: list[tuple[int, str]],
                  texts: list[tuple[str | None, int, str]]) -> list[tuple[str, list[str]]]:
        """DATA sections in file order with their instances' text, then the comments of the
        unreadable text in them (``texts``: section, line, comment); one ``DATA;`` unless the
        graph records several (instances without a section go to the first, texts to the last)."""
        section_of = {key: _key(v[0]) for _, key in instances if (v := self.props[key].get(P21_SECTION))}
        keys = set(section_of.values()) | {s for s, _, _ in texts if s is not None}
        order = sorted(keys, key=lambda s: int(self._first(s, "sectionIndex") or 0)) or [""]
        members: dict[str, list[str]] = {s: [] for s in order}
        for s in order:  # an opener lenient mode repaired: the text as read, in a comment
            if raw := (self._first(s, "rawText") if s else None):
                members[s].append(comment(f"stepnc-graph: this DATA section's opening as read: {raw}"))
        for i, key in instances:
            members[section_of.get(key, order[0])].append(self._instance(i, key))
        for section, _, text in sorted(texts, key=lambda t: t[1]):
            members[section if section is not None else order[-1]].append(text)
        return [(self._first(s, "sectionText") or "DATA;" if s else "DATA;", members[s]) for s in order]

    def _unreadable_texts(self, meta: str) -> list[tuple[str | None, int, str]]:
        """The graph's ``p21:unreadableText``: (its DATA section, if recorded; line; the comment
        that writes it)."""
        out = []
        for node in (_key(n) for n in self.props.get(meta, {}).get(P21_UNREADABLE_TEXT, [])):
            sections = self.props[node].get(P21_SECTION)
            line = int(self._first(node, "line") or 0)
            why = self._first(node, "syntaxError") or "a syntax error"
            out.append((_key(sections[0]) if sections else None, line, comment(
                f"stepnc-graph: text at line {line} could not be read ({why}): {self._first(node, 'rawText') or ''}")))
        return out

    def _first(self, key: str, term: str) -> str | None:
        """The value of the node's first ``p21:<term>`` triple, if it has one: a literal's text (an
        IRI or blank node where text belongs -- a graph edited by hand or a damaged JSON-LD
        document -- would be written into the file as if it were Part 21)."""
        values = self.props.get(key, {}).get(f"<{P21_NS}{term}>")
        if not values:
            return None
        if not isinstance(values[0], ox.Literal):
            raise WriteError(f"{key} has p21:{term} {values[0]}, which is not a literal")
        return str(values[0].value)

    def _schemas(self, props: dict[str, Any], graph: str | None) -> list[str]:
        if graph is not None and f"<{graph}>" in props:
            names = [t.value for t in props[f"<{graph}>"].get(f"<{P21_NS}schemaName>", [])]
            if names:
                return names
        return ["MACHINING_SCHEMA", "MILLING_SCHEMA", "TURNING_SCHEMA"]

    def _instances(self, props: dict[str, dict[str, list[Any]]]) -> list[tuple[int, str]]:
        numbered: list[tuple[int, str]] = []
        unnumbered: list[str] = []
        for key, p in props.items():
            if not key.startswith("<"):
                continue
            ids = p.get(P21_ID)
            if ids:
                numbered.append((self._id(key, ids), key))
            elif any(f"<{t.value}>" == P21_RAW or t.value in self.plans.by_class for t in p.get(RDF_TYPE, [])):
                unnumbered.append(key)
        first: dict[int, str] = {}
        for i, key in numbered:
            if first.setdefault(i, key) != key:
                raise WriteError(f"{first[i]} and {key} both have p21:id {i}: a Part 21 file defines each #id once")
        next_id = max((i for i, _ in numbered), default=0) + 1
        for key in sorted(unnumbered):
            numbered.append((next_id, key))
            next_id += 1
        return sorted(numbered)

    @staticmethod
    def _id(key: str, ids: list[Any]) -> int:
        """The node's one ``p21:id``, a whole number (a graph edited by hand may hold other values)."""
        if len(ids) != 1:
            raise WriteError(f"{key} has {len(ids)} p21:id values: an instance has one #id")
        text = ids[0].value if isinstance(ids[0], ox.Literal) else ""
        try:
            if text.isascii() and text.isdigit():
                return int(text)
        except ValueError:  # longer than int() reads (4,300 digits): no name the reader accepts either
            pass
        raise WriteError(f"{key} has p21:id {ids[0]}, which is no instance number")

    # -- instances ------------------------------------------------------------------

    def _instance(self, p21_id: int, key: str) -> str:
        text = self._instance_text(p21_id, key)
        later = [(int(self._first(_key(n), "line") or 0), self._first(_key(n), "rawText") or "")
                 for n in self.props[key].get(P21_DUPLICATE, [])]
        return text + "".join("\n" + comment(f"stepnc-graph: a later definition of #{p21_id} (line {line}), not "
                                             f"loaded: {raw}") for line, raw in sorted(later))

    def _instance_text(self, p21_id: int, key: str) -> str:
        p = self.props[key]
        types = [t.value for t in p.get(RDF_TYPE, [])]
        if P21_UNREADABLE[1:-1] in types:
            why = self._first(key, "syntaxError") or "a syntax error"
            return comment(f"stepnc-graph: #{p21_id} could not be read ({why}); its text: "
                           f"{p[P21_RAW_TEXT][0].value if P21_RAW_TEXT in p else ''}")
        if P21_RAW[1:-1] in types:
            return self._raw_text(p21_id, key)
        own = self._first(key, "edition")
        if own is not None:
            return self._in_edition(own)._entity_text(p21_id, key, types)
        return self._entity_text(p21_id, key, types)

    def _entity_text(self, p21_id: int, key: str, types: list[str]) -> str:
        plans = [self.plans.by_class[t] for t in types if t in self.plans.by_class]
        if not plans:
            raise WriteError(f"{key} (#{p21_id}) has no entity type of the schema")
        if len(plans) == 1:
            return f"#{p21_id}={plans[0].name.upper()}({self._params(key, plans[0].slots)});"
        model = self.plans.model
        leaves = [pl for pl in plans if not any(o is not pl and model.is_subtype(o.name, pl.name) for o in plans)]
        parts = "".join(f"{pl.name.upper()}({self._params(key, pl.own_slots)})"
                        for pl in sorted(leaves, key=lambda pl: pl.name))
        return f"#{p21_id}=({parts});"

    def _raw_text(self, p21_id: int, key: str) -> str:
        """A raw instance's kept text (repaired where the reader repaired it), written as it is: so
        it must read back as this one instance (a graph edited by hand may hold any string)."""
        p = self.props[key]
        texts = p.get(P21_REPAIRED_TEXT) or p.get(P21_RAW_TEXT) or []
        if len(texts) != 1 or not isinstance(texts[0], ox.Literal):
            raise WriteError(f"{key} (#{p21_id}) is a p21:RawInstance without one text literal (p21:rawText)")
        text = str(texts[0].value)
        try:
            found = read_instance(text)
        except Part21SyntaxError as e:
            raise WriteError(f"{key} (#{p21_id}): its p21:rawText is not one Part 21 instance ({e.message})") from None
        if found.id != p21_id:
            raise WriteError(f"{key} has p21:id {p21_id} but its p21:rawText defines #{found.id}")
        return text

    def _params(self, key: str, slots: tuple[Slot, ...]) -> str:
        p = self.props[key]
        derived = {t.value for t in p.get(P21_DERIVED, [])}
        empty = {t.value for t in p.get(P21_EMPTY, [])}
        out = []
        for slot in slots:
            values = p.get(f"<{slot.prop}>", [])
            if slot.prop in derived:
                out.append("*")
            elif slot.repeated:
                if slot.prop in empty:
                    out.append("()")
                elif values:
                    out.append("(" + ",".join(sorted((self._value(slot.encoding, v) for v in values), key=_set_order))
                               + ")")
                else:
                    out.append("$")
            elif values:
                out.append(self._value(slot.encoding, values[0]))
            else:
                out.append("$")
        return ",".join(out)

    # -- values -----------------------------------------------------------------------

    def _ref(self, term: Any) -> str:
        key = _key(term)
        if key in self.ids:
            return f"#{self.ids[key]}"
        m = _TRAILING_ID.search(term.value)
        if m:  # an unresolved reference kept from the source file
            return f"#{m.group(1)}"
        raise WriteError(f"{term.value} is not an instance of the graph")

    def _value(self, enc: Encoding, term: Any) -> str:
        if isinstance(term, ox.Literal):
            return self._literal(enc, term)
        if isinstance(term, ox.BlankNode):
            key = _key(term)
            p = self.props.get(key, {})
            if f"<{RDF}first>" in p or key == f"<{RDF}nil>":
                return self._list(enc, term)
            types = [t.value for t in p.get(RDF_TYPE, [])]
            for t in types:
                if t in self.typed_names:
                    inner = enc.typed[self.typed_names[t]][1]
                    return f"{self.typed_names[t]}({self._value(inner, p[P21_VALUE][0])})"
            raise WriteError(f"blank node {key} is neither a list nor a typed value")
        if term.value == RDF + "nil":
            return "()"
        if f"<{term.value}>" == P21_UNSET:
            return "$"
        if term.value in self.enum_items:
            return f".{self.enum_items[term.value]}."
        return self._ref(term)

    def _list(self, enc: Encoding, head: Any) -> str:
        element = enc.element or enc
        items = []
        node = head
        seen = 0
        while not (isinstance(node, ox.NamedNode) and node.value == RDF + "nil"):
            p = self.props.get(_key(node))
            if not p or seen > 10_000_000:
                raise WriteError("malformed rdf:List")
            items.append(self._value(element, p[f"<{RDF}first>"][0]))
            node = p[f"<{RDF}rest>"][0]
            seen += 1
        return "(" + ",".join(items) + ")"

    def _literal(self, enc: Encoding, lit: ox.Literal) -> str:
        dt = lit.datatype.value
        if dt == XSD + "double" or dt == XSD + "decimal" or dt == XSD + "float":
            return format_real(float(lit.value))
        if dt == XSD + "integer":
            return lit.value if enc.kind != "real" else format_real(float(lit.value))
        if dt == XSD + "boolean":
            return ".T." if lit.value in ("true", "1") else ".F."
        if dt == P21_UNKNOWN:
            return ".U."
        if dt == XSD + "hexBinary":
            return f'"0{lit.value}"'
        return encode(lit.value)


def _check_frame(graph: str | None, header: str, extra: str, openers: list[str]) -> None:
    """Refuse kept text that would not read back as what it stands for: the header, the ANCHOR and
    REFERENCE sections and each DATA section's opening are written verbatim from the graph, so a
    graph edited by hand (or a damaged JSON-LD document) could make them anything -- a broken file,
    or instances no instance node stands for. The frame alone (no instances) must read strictly as
    a Part 21 file with no instances; it is a few lines, so this costs nothing next to the body."""
    frame = "ISO-10303-21;\n" + header + "\n" + extra + "".join(f"{o}\nENDSEC;\n" for o in openers) + "END-ISO-10303-21;\n"
    where = f"<{graph}>" if graph is not None else "the graph"
    try:
        found = sum(1 for _ in read_text(frame, "frame").instances())
    except Part21SyntaxError as e:
        raise WriteError(f"{where}: its kept header or section text does not read back as Part 21 ({e.message}: "
                         f"{e.text.strip() if e.text else ''})") from None
    if found:
        raise WriteError(f"{where}: its kept header or section text holds {found} instance(s) of its own")


def write_graph(plans: Plans, quads: Iterable[ox.Quad] | Iterable[ox.Triple], graph: str | None = None) -> str:
    return Part21Writer(plans).write(quads, graph)

