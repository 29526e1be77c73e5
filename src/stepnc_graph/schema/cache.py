"""The compiled schema model: ``ontology/compiled-model.json``, read instead of the EXPRESS.

Parsing and resolving the EXPRESS schemas takes most of a second, which would
be the whole cost of a command run on a small program. ``stepnc-graph ontology
build`` therefore writes the resolved model (and the mapping plans, see
:mod:`stepnc_graph.mapping.plans`) to one JSON file shipped in the wheel beside
the vocabulary. JSON, not pickle: reading it runs no code from the file.

What the file holds:

* ``express_sha256``: the digest of ``ontology/express/`` it was built from
  (:func:`express_digest`), and ``records_sha256``, the digest of the lines
  after the first (the records), so an edited or damaged file is caught too.
  A file whose digests or ``format`` do not match is stale: :func:`shipped`
  then warns (:class:`CompiledModelWarning`) and builds the model from the
  EXPRESS, never using the stale file. ``ontology build --check`` compares the
  file with a fresh build like every generated file, which also catches a
  change of the builder's code.
* the catalogue (``schemas.toml`` without its directory), every schema and
  every declaration with all their fields, source positions included, with
  file names relative to ``ontology/express/`` so the file is the same in
  every checkout;
* **not** the parsed expression trees of WHERE rules (``WhereRule.expr``,
  excluded from comparisons): only the generators use them, and they run from
  the EXPRESS. In a model read from this file ``expr`` is ``None``; the rule's
  label, source text and position are there.
* ``plans``: the mapping plans, opaque to this module.

Types are written compactly (a bare string is a ``NamedType``) and each record
is one line, so a schema change shows as a readable diff.
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from stepnc_graph.core.errors import StepncGraphWarning
from stepnc_graph.core.resources import sources_digest
from stepnc_graph.schema.catalog_file import Catalog, load_catalog_model
from stepnc_graph.schema.model import (
    AggregateType,
    Attribute,
    BaseType,
    Declaration,
    DefinedType,
    Entity,
    EnumerationType,
    GenericType,
    Interface,
    Redeclaration,
    SchemaInfo,
    SelectType,
    SimpleType,
    NamedType,
    SourcePos,
    SupertypeExpr,
    SupertypeOperand,
    TypeRef,
    UniqueRule,
    WhereRule,
)
from stepnc_graph.schema.view import SchemaModel

#: The file's name inside ``ontology/``.
CACHE_FILE = "compiled-model.json"
#: Bumped whenever the layout below changes; a file of another format is stale.
FORMAT = 1

JSON = Any


class CompiledModelWarning(StepncGraphWarning):
    """The compiled model is missing or stale; the model was built from the EXPRESS instead."""


class StaleCache(Exception):
    """A compiled-model file that must not be used (missing, stale, unreadable)."""


def express_digest(directory: Path) -> str:
    """SHA-256 over every file of ``directory`` (relative name and content), in name order.

    Line ends are normalised to LF first, so a checkout that converts them
    does not make the shipped file stale.
    """
    files = sorted(p for p in directory.rglob("*") if p.is_file() and not _hidden(p.relative_to(directory)))
    return sources_digest((p.relative_to(directory).as_posix(), p.read_bytes()) for p in files)


def _hidden(rel: Path) -> bool:
    return any(part.startswith(".") or part == "__pycache__" for part in rel.parts)


# -- writing -------------------------------------------------------------------


class _Encoder:
    """Model objects -> JSON values; source files become indexes into ``files``."""

    def __init__(self, directory: Path) -> None:
        self.prefix = str(directory) + os.sep
        self.files: list[str] = []

    def file(self, name: str) -> int:
        if not name.startswith(self.prefix):
            raise ValueError(f"{name} is not under {self.prefix}: the compiled model stores relative names")
        rel = Path(name[len(self.prefix):]).as_posix()
        if rel not in self.files:
            self.files.append(rel)
        return self.files.index(rel)

    def pos(self, p: SourcePos | None) -> JSON:
        return None if p is None else [self.file(p.file), p.line, p.column]

    def type(self, t: TypeRef) -> JSON:
        if isinstance(t, NamedType):
            return t.name
        if isinstance(t, SimpleType):
            return ["simple", t.base.value, t.width, t.fixed]
        if isinstance(t, AggregateType):
            return ["aggregate", t.kind, self.type(t.element), t.lower, t.upper, t.unique, t.optional_elements,
                    t.bound_text]
        return ["generic", t.label]

    def supertype_expr(self, e: SupertypeOperand | None) -> JSON:
        if e is None or isinstance(e, str):
            return e
        return [e.op, [self.supertype_expr(o) for o in e.operands]]

    def where(self, rules: tuple[WhereRule, ...]) -> JSON:
        return [[r.label, r.source, self.pos(r.pos)] for r in rules]

    def attribute(self, a: Attribute) -> JSON:
        return [a.name, self.type(a.type), a.kind, a.optional, a.expression,
                list(a.inverse_of) if a.inverse_of else None, self.pos(a.pos)]

    def redeclaration(self, r: Redeclaration) -> JSON:
        return [r.supertype, r.name, self.type(r.type), r.optional, r.derived, r.renamed_to, self.pos(r.pos)]

    def declaration(self, d: Declaration) -> JSON:
        head = {"name": d.name, "schema": d.schema, "pos": self.pos(d.pos)}
        if isinstance(d, Entity):
            return {"kind": "entity", **head, "supertypes": list(d.supertypes), "abstract": d.abstract,
                    "supertype_expr": self.supertype_expr(d.supertype_expr),
                    "attributes": [self.attribute(a) for a in d.attributes],
                    "redeclarations": [self.redeclaration(r) for r in d.redeclarations],
                    "unique_rules": [[u.label, list(u.attributes)] for u in d.unique_rules],
                    "where_rules": self.where(d.where_rules)}
        rules = {"where_rules": self.where(d.where_rules)}
        if isinstance(d, DefinedType):
            return {"kind": "defined", **head, "underlying": self.type(d.underlying), **rules}
        members = d.items if isinstance(d, EnumerationType) else d.members
        return {"kind": "enumeration" if isinstance(d, EnumerationType) else "select", **head,
                "members": list(members), "extensible": d.extensible, "based_on": d.based_on, **rules}

    def schema(self, s: SchemaInfo) -> JSON:
        return {"name": s.name, "file": self.file(s.file),
                "interfaces": [[i.kind, i.schema, None if i.items is None else [list(x) for x in i.items],
                                self.pos(i.pos)] for i in s.interfaces],
                "declarations": list(s.declarations), "constants": list(s.constants),
                "functions": list(s.functions), "rules": list(s.rules), "iso_part": s.iso_part, "title": s.title,
                "edition": s.edition, "version": s.version, "status": s.status, "source": s.source,
                "clauses": s.clauses}


def dumps(catalog: Catalog, model: SchemaModel, plans: JSON, digest: str) -> str:
    """The compiled-model file's text: byte-stable for the same model, plans and digest."""
    enc = _Encoder(catalog.directory)
    schemas = [enc.schema(s) for s in model.schemas.values()]
    declarations = [enc.declaration(d) for d in model.declarations.values()]
    records = ",\n".join([
        _line({"catalog": {"files": list(catalog.files), "schemas": catalog.schemas, "namespace": catalog.namespace,
                           "ontology_base": catalog.ontology_base, "ontology_version": catalog.ontology_version},
               "files": enc.files})[1:-1],
        _records("schemas", schemas),
        _records("declarations", declarations),
        f'"plans":{{{_records_body(plans)}}}}}\n',
    ])
    head = _line({"format": FORMAT, "express_sha256": digest, "records_sha256": _sha256(records)})[:-1]
    return f"{head},\n{records}"


def _sha256(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def _line(value: JSON) -> str:
    return json.dumps(value, ensure_ascii=False, separators=(",", ":"))


def _records(key: str, items: list[JSON]) -> str:
    return f'"{key}":[\n' + ",\n".join(_line(i) for i in items) + "\n]"


def _records_body(plans: dict[str, list[JSON]]) -> str:
    """Each list in ``plans`` one record a line, like the model's own lists."""
    return ",\n".join(_records(k, v) for k, v in plans.items())


# -- reading -------------------------------------------------------------------


class _Decoder:
    """JSON values -> model objects; the inverse of :class:`_Encoder`."""

    def __init__(self, directory: Path, files: list[str]) -> None:
        self.files = [str(directory / f) for f in files]

    def pos(self, p: JSON) -> SourcePos | None:
        if p is None:
            return None
        return SourcePos(self.files[p[0]], p[1], p[2])

    def type(self, t: JSON) -> TypeRef:
        if type(t) is str:
            return NamedType(t)
        tag = t[0]
        if tag == "simple":
            return SimpleType(BaseType(t[1]), t[2], t[3])
        if tag == "aggregate":
            return AggregateType(t[1], self.type(t[2]), t[3], t[4], t[5], t[6], t[7])
        if tag == "generic":
            return GenericType(t[1])
        raise StaleCache(f"unknown type record {t!r}")

    def supertype_expr(self, e: JSON) -> SupertypeExpr | None:
        return None if e is None else self.operand(e)  # type: ignore[return-value]

    def operand(self, e: JSON) -> SupertypeOperand:
        return e if type(e) is str else SupertypeExpr(e[0], tuple(self.operand(o) for o in e[1]))

    def where(self, rules: JSON) -> tuple[WhereRule, ...]:
        return tuple(WhereRule(label, source, None, self.pos(p)) for label, source, p in rules)

    def attribute(self, entity: str, a: JSON) -> Attribute:
        return Attribute(a[0], entity, self.type(a[1]), a[2], a[3], a[4], tuple(a[5]) if a[5] else None,
                         self.pos(a[6]))

    def redeclaration(self, entity: str, r: JSON) -> Redeclaration:
        return Redeclaration(entity, r[0], r[1], self.type(r[2]), r[3], r[4], r[5], self.pos(r[6]))

    def entity(self, d: JSON) -> Entity:
        name = d["name"]
        return Entity(name, d["schema"], tuple(d["supertypes"]), d["abstract"],
                      self.supertype_expr(d["supertype_expr"]),
                      tuple(self.attribute(name, a) for a in d["attributes"]),
                      tuple(self.redeclaration(name, r) for r in d["redeclarations"]),
                      tuple(UniqueRule(label, tuple(attrs)) for label, attrs in d["unique_rules"]),
                      self.where(d["where_rules"]), self.pos(d["pos"]))

    def defined(self, d: JSON) -> DefinedType:
        return DefinedType(d["name"], d["schema"], self.type(d["underlying"]), self.where(d["where_rules"]),
                           self.pos(d["pos"]))

    def enumeration(self, d: JSON) -> EnumerationType:
        return EnumerationType(d["name"], d["schema"], tuple(d["members"]), d["extensible"], d["based_on"],
                               self.where(d["where_rules"]), self.pos(d["pos"]))

    def select(self, d: JSON) -> SelectType:
        return SelectType(d["name"], d["schema"], tuple(d["members"]), d["extensible"], d["based_on"],
                          self.where(d["where_rules"]), self.pos(d["pos"]))

    def declaration(self, d: JSON) -> Declaration:
        decode: dict[str, Callable[[JSON], Declaration]] = {
            "entity": self.entity, "defined": self.defined, "enumeration": self.enumeration, "select": self.select}
        return decode[d["kind"]](d)

    def schema(self, s: JSON) -> SchemaInfo:
        interfaces = tuple(Interface(kind, schema, None if items is None else tuple(tuple(x) for x in items),
                                     self.pos(p)) for kind, schema, items, p in s["interfaces"])
        return SchemaInfo(s["name"], self.files[s["file"]], interfaces, tuple(s["declarations"]),
                          tuple(s["constants"]), tuple(s["functions"]), tuple(s["rules"]), s["iso_part"],
                          s["title"], s["edition"], s["version"], s["status"], s["source"], s["clauses"])


@dataclass(frozen=True)
class Compiled:
    """A catalogue and its model, with the mapping plans' data when read from the file."""

    catalog: Catalog
    model: SchemaModel
    plans: JSON | None = None


def loads(text: str, directory: Path, digest: str) -> Compiled:
    """Decode a compiled-model file for the EXPRESS in ``directory`` (digest ``digest``).

    Raises :class:`StaleCache` when the file is of another format or digest, or
    does not decode.
    """
    try:
        data = json.loads(text)
        if data.get("format") != FORMAT:
            raise StaleCache(f"it has format {data.get('format')!r}, this stepnc-graph reads format {FORMAT}")
        if data.get("express_sha256") != digest:
            raise StaleCache("ontology/express/ changed since it was built")
        if data.get("records_sha256") != _sha256(text.partition("\n")[2]):
            raise StaleCache("its records were changed after it was built")
        c = data["catalog"]
        catalog = Catalog(directory, tuple(c["files"]), c["schemas"], c["namespace"], c["ontology_base"],
                          c["ontology_version"])
        dec = _Decoder(directory, data["files"])
        schemas = {s["name"]: dec.schema(s) for s in data["schemas"]}
        declarations = {d["name"]: dec.declaration(d) for d in data["declarations"]}
        return Compiled(catalog, SchemaModel(schemas, declarations), data["plans"])
    except (ValueError, KeyError, IndexError, TypeError) as exc:
        raise StaleCache(f"it does not decode ({type(exc).__name__}: {exc})") from exc


def read(ontology: Path) -> Compiled:
    """The compiled model in ``ontology/`` for the EXPRESS in ``ontology/express/``."""
    path = ontology / CACHE_FILE
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise StaleCache(f"it cannot be read ({exc.strerror or exc})") from exc
    return loads(text, ontology / "express", express_digest(ontology / "express"))


def load_or_build(ontology: Path) -> Compiled:
    """The compiled model in ``ontology/``, or, if it is missing or stale, one built from the EXPRESS.

    The fallback warns (:class:`CompiledModelWarning`), so a stale file is never
    used and never ignored silently.
    """
    try:
        return read(ontology)
    except StaleCache as exc:
        warnings.warn(f"{ontology / CACHE_FILE} is not used: {exc}. Building the schema model from the "
                      f"EXPRESS instead (about a second); `stepnc-graph ontology build` refreshes the file.",
                      CompiledModelWarning, stacklevel=2)
    catalog, model = load_catalog_model(ontology / "express")
    return Compiled(catalog, model)


@lru_cache(maxsize=1)
def shipped() -> Compiled:
    """The shipped ISO 14649 model (see :func:`load_or_build`), once per process."""
    from stepnc_graph.core.resources import ontology_dir

    return load_or_build(ontology_dir())
