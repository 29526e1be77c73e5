"""``ontology/context.jsonld``: the JSON-LD 1.1 context of program graphs, from the mapping plans.

A PLM integrator reads and writes keys such as ``its_id`` and ``its_operation``,
not ``stepnc:machining_workingstep.its_operation``. The context gives them:

* one term per class (``machining_workingstep``), used as ``@type``, with a
  **type-scoped context** holding a short term for each of the entity's Part 21
  attributes, inherited ones included, in Part 21 order (so ``its_id`` inside a
  ``machining_workingstep`` means ``stepnc:executable.its_id``); type-scoped
  contexts do not reach nested nodes, so each node reads its keys with its own
  type's terms;
* ``@container: @list`` for LIST, ARRAY and BAG attributes (an ``rdf:List`` in
  the graph), ``@container: @set`` for SETs (always an array);
* ``@type: @id`` for references (written relative to ``@base``, which an export
  sets to its graph), ``@type: @vocab`` with a property-scoped context naming
  the items for enumerations (``"feedrate_reference": "tcp"``);
* datatype coercion, so values keep their datatype whatever a consumer does with
  JSON numbers: REAL attributes are ``xsd:double`` (an export writes the exact
  lexical form as a string, and a JavaScript program that writes back the number
  ``2`` still gives the double 2.0E0), INTEGER ``xsd:integer``, BINARY
  ``xsd:hexBinary``;
* the prefixes ``stepnc:``, ``p21:``, ``rdf:``, ``rdfs:``, ``owl:``, ``xsd:``,
  ``dcterms:`` and ``prov:`` for everything else.

It is derived from the same plans the loader and the Part 21 writer use, so a
term means exactly the property the loader writes. A short name that would be
ambiguous (two attributes of one class with the same name, an attribute or item
named like a prefix or a class) gets no term: the export writes the compact IRI.
"""

from __future__ import annotations

import json
from typing import Any

from stepnc_graph.mapping.plans import Encoding, EntityPlan, Plans, Slot
from stepnc_graph.core.naming import P21_NS, Naming

PREFIXES = {
    "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#",
    "rdfs": "http://www.w3.org/2000/01/rdf-schema#",
    "owl": "http://www.w3.org/2002/07/owl#",
    "xsd": "http://www.w3.org/2001/XMLSchema#",
    "dcterms": "http://purl.org/dc/terms/",
    "prov": "http://www.w3.org/ns/prov#",
}
XSD = PREFIXES["xsd"]
#: datatype coercion of literal attributes; strings, booleans and LOGICALs are
#: JSON's own (a JSON string is an xsd:string, true/false xsd:boolean)
_COERCED = {"real": "xsd:double", "integer": "xsd:integer", "binary": "xsd:hexBinary"}


def context(naming: Naming) -> dict[str, str]:
    """The prefixes (Turtle and TriG exports declare the same ones)."""
    return {"stepnc": naming.namespace, "p21": P21_NS, **PREFIXES}


def _leaf(encoding: Encoding) -> Encoding:
    while encoding.kind == "list" and encoding.element is not None:
        encoding = encoding.element
    return encoding


def _typed_encodings(plans: Plans) -> dict[str, Encoding]:
    """Class IRI -> encoding of the underlying type, for every defined type written as a typed node."""
    found: dict[str, Encoding] = {}
    stack = [slot.encoding for plan in plans.entities.values() for slot in plan.slots]
    seen: set[int] = set()
    while stack:
        encoding = stack.pop()
        if id(encoding) in seen:
            continue
        seen.add(id(encoding))
        for cls, inner in encoding.typed.values():
            found.setdefault(cls, inner)
            stack.append(inner)
        if encoding.element is not None:
            stack.append(encoding.element)
    return found


class ContextBuilder:
    """The context as a JSON value, from the plans of a model."""

    def __init__(self, plans: Plans, naming: Naming) -> None:
        self.plans = plans
        self.n = naming
        self.prefixes = context(naming)
        self.class_names = {plan.name.lower() for plan in plans.entities.values()} | {
            name.lower() for name in plans.typed_names.values()}
        self.reserved = set(self.prefixes) | self.class_names
        self.typed = _typed_encodings(plans)

    def compact(self, iri: str) -> str:
        """``stepnc:x`` / ``p21:x`` for the vocabulary's own IRIs."""
        for prefix in ("stepnc", "p21"):
            if iri.startswith(self.prefixes[prefix]):
                return f"{prefix}:{iri[len(self.prefixes[prefix]):]}"
        return iri

    def build(self) -> dict[str, Any]:
        ctx: dict[str, Any] = {"@version": 1.1, **dict(sorted(self.prefixes.items()))}
        terms: dict[str, Any] = {}
        for plan in self.plans.entities.values():
            terms[plan.name.lower()] = self.class_term(plan)
        for cls, name in self.plans.typed_names.items():
            terms[name.lower()] = self.typed_term(cls, name)
        ctx.update(sorted(terms.items()))
        return ctx

    def class_term(self, plan: EntityPlan) -> Any:
        scoped: dict[str, Any] = {}
        names = [slot.name.lower() for slot in plan.slots]
        for slot in plan.slots:
            name = slot.name.lower()
            if names.count(name) == 1 and name not in self.prefixes:
                scoped[name] = self.attribute_term(slot)
        iri = self.compact(plan.cls)
        return {"@id": iri, "@context": scoped} if scoped else iri

    def typed_term(self, cls: str, name: str) -> Any:
        """A defined type whose values are written as typed nodes (inside a SELECT): ``value`` coerced."""
        inner = self.typed[cls]
        value: dict[str, Any] = {"@id": "p21:value", **self.coercion(inner)}
        if inner.kind == "list":
            value["@container"] = "@list"
        return {"@id": self.compact(cls), "@context": {"value": value}}

    def attribute_term(self, slot: Slot) -> Any:
        term: dict[str, Any] = {"@id": self.compact(slot.prop)}
        if slot.repeated:
            term["@container"] = "@set"
        elif slot.encoding.kind == "list":
            term["@container"] = "@list"
        term.update(self.coercion(slot.encoding))
        return term["@id"] if len(term) == 1 else term

    def coercion(self, encoding: Encoding) -> dict[str, Any]:
        """``@type`` (and the items' property-scoped context) for values of ``encoding``."""
        leaf = _leaf(encoding)
        if leaf.kind in _COERCED:
            return {"@type": _COERCED[leaf.kind]}
        if leaf.kind == "entity" or (leaf.kind == "select" and leaf.accepts_refs):
            return {"@type": "@id"}
        if leaf.kind == "enum" or (leaf.kind == "select" and leaf.items and not leaf.typed):
            items = {item.lower(): self.compact(iri) for item, iri in sorted(leaf.items.items())
                     if item.lower() not in self.reserved}
            return {"@type": "@vocab", "@context": items} if items else {"@type": "@vocab"}
        return {}


def context_document(plans: Plans, naming: Naming) -> dict[str, Any]:
    """The context document (``{"@context": {...}}``) for ``plans``."""
    return {"@context": ContextBuilder(plans, naming).build()}


def dumps(document: dict[str, Any]) -> str:
    """The context document as text: one line per term of a class, so diffs stay readable."""
    ctx = document["@context"]
    lines = []
    for key, value in ctx.items():
        if isinstance(value, dict) and "@context" in value:
            inner = ",\n".join(f"      {json.dumps(k)}: {json.dumps(v, ensure_ascii=False)}"
                               for k, v in value["@context"].items())
            head = f'    {json.dumps(key)}: {{"@id": {json.dumps(value["@id"])}, "@context": {{'
            lines.append(f"{head}\n{inner}\n    }}}}")
        else:
            lines.append(f"    {json.dumps(key)}: {json.dumps(value, ensure_ascii=False)}")
    return '{\n  "@context": {\n' + ",\n".join(lines) + "\n  }\n}\n"


class JsonLdContextGenerator:
    """Writes ``context.jsonld``; documents name it by :data:`~stepnc_graph.core.naming.CONTEXT_IRI`."""

    def __init__(self, plans: Plans, naming: Naming) -> None:
        self.plans = plans
        self.n = naming

    def outputs(self) -> dict[str, str]:
        document = context_document(self.plans, self.n)
        text = dumps(document)
        assert json.loads(text) == document  # the layout changes no value
        return {"context.jsonld": text}
