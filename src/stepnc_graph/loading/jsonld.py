"""Load a JSON-LD document of a program graph (what ``export --format jsonld`` wrote, maybe
edited by a PLM system) as that program's named graph, so that the Part 21 export gives the
program back.

**No network, no files, ever.** A JSON-LD processor loads every context a document names
by IRI (``"@context": "https://..."``, ``@import``, a scoped context, at any depth of a
context array), which would let a document make stepnc-graph open connections, read local
files, or load term definitions that change what the data means. Two things stop it:

* the processor has no way to load a document: it is Oxigraph's (``pyoxigraph``, a
  dependency already), whose Python binding gives its JSON-LD parser no document loader, so a
  context named by IRI is an error in the processor itself, never a request;
* before the processor sees the document, a walk over all of it (:func:`local_contexts`)
  puts the installed ``ontology/context.jsonld`` where the shipped context's IRI
  (:data:`~stepnc_graph.core.naming.CONTEXT_IRI`) is named, and refuses any other IRI -- in a
  document, node, type- or property-scoped context, a nested array, ``@import`` -- with the
  JSON pointer of where it is.

**Nothing dropped.** JSON-LD silently drops what it cannot turn into RDF: a node whose
``@id`` is not a valid IRI, a key the context does not define, a key that looks like a
keyword, a bad language tag. The document is therefore read twice by the processor: as
JSON-LD says, and leniently (invalid IRIs kept). When the two differ, the load is refused,
naming each invalid value and where it is. JSON reading refuses a key given twice in one
object (JSON keeps the last), a number JSON-LD would turn into an ``xsd:double`` that cannot
hold it, nesting deeper than :data:`MAX_DEPTH` and an ``@id`` longer than :data:`MAX_IRI`.
Messages speak of the document (its JSON pointers, its values), not of the code that read it.

**Which graph.** The document names its graph (the top-level ``@id`` of an
export); it is loaded as that graph, unless ``--base-iri`` gives another, in
which case the document's IRIs under its graph move under the new one. A
document without a named graph is loaded as the graph its file name gives.

**What is replaced.** The graph's load metadata describes the load that wrote
it, as for a Part 21 file: ``dcterms:source``, ``prov:hadPrimarySource``,
``p21:byteSize``/``p21:sha256`` (of the JSON-LD file), the counts,
``prov:generatedAtTime`` and the load activity are those of this load; the
program the document was exported from stays visible as ``prov:wasDerivedFrom``
its primary source. The ``its_id`` aliases are recomputed from the data (a PLM
system may have renamed a workingstep). Everything else -- instances, HEADER
text, edition-3 sections, triples a PLM system added -- is stored as the
document says.
"""

from __future__ import annotations

import hashlib
import json
import re
import time
from collections import defaultdict
from collections.abc import Iterator
from functools import lru_cache
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.version import __version__
from stepnc_graph.loading.common import DCT, PROV, RDFS, LoadResult, Progress, load_timestamp
from stepnc_graph.mapping.editions import EDITIONS, edition_plans
from stepnc_graph.mapping.plans import Plans, iso14649_plans
from stepnc_graph.core.naming import P21_NS, TOOL_IRI, alias_iri, instance_prefix
from stepnc_graph.part21.diagnostics import Diagnostic
from stepnc_graph.loading.common import Source
from stepnc_graph.store import Store
from stepnc_graph.loading.jsonld_problems import (dropped_error, locate, masked, path_of, invalid_terms, processor_error,
                                                  relabelled, named_graph_of)
from stepnc_graph.loading.jsonld_read import MAX_DEPTH, MAX_IRI, JsonLdError, quote, parse_json, pointer, read_bytes
from stepnc_graph.loading.jsonld_walk import local_contexts

__all__ = ["CHUNK_TRIPLES", "LOAD_PREDICATES", "MAX_DEPTH", "MAX_IRI", "JsonLdError", "JsonLdLoad", "local_contexts",
           "named_graph_of", "parse_quads", "program_graph"]


RDF_TYPE = "http://www.w3.org/1999/02/22-rdf-syntax-ns#type"
XSD = "http://www.w3.org/2001/XMLSchema#"
OWL_SAME_AS = "http://www.w3.org/2002/07/owl#sameAs"
#: what the graph says about its load: replaced by this load's values
LOAD_PREDICATES = frozenset({
    DCT + "source", PROV + "hadPrimarySource", P21_NS + "byteSize", P21_NS + "sha256", P21_NS + "instanceCount",
    P21_NS + "rawInstanceCount", P21_NS + "diagnosticCount", PROV + "generatedAtTime", PROV + "wasGeneratedBy"})
CHUNK_TRIPLES = 20000


#: the p21: properties the Part 21 writer reads as whole numbers: (how a message names them)
_NUMBERED = {P21_NS + "id": ("p21:id", "instance number"), P21_NS + "line": ("p21:line", "line number"),
             P21_NS + "sectionIndex": ("p21:sectionIndex", "section number")}
_WHOLE = re.compile(r"[0-9]{1,18}")


# -- the processor ----------------------------------------------------------------------------------


def parse_quads(doc: Any, base: str, name: str) -> list[ox.Quad]:
    """The quads of a JSON-LD document (its contexts resolved by :func:`local_contexts`).

    Oxigraph's JSON-LD processor reads it; it cannot load a document (its binding gives it
    no loader), so a context named by IRI is an error here too. JSON-LD drops a statement
    whose IRI, blank node label or language tag is not valid; the processor is therefore
    run leniently, keeping them, and every term is checked: an invalid one is a
    :class:`JsonLdError` naming it and where it is. Lenient resolution of a reference with
    dot segments can make an invalid one valid (``"a b/../c"``); a document that has such
    segments is read a second time as JSON-LD says, and the two must agree.
    """
    data = json.dumps(doc).encode("utf-8")
    try:
        quads = list(ox.parse(data, ox.RdfFormat.JSON_LD, base_iri=base, lenient=True))
    except SyntaxError as e:
        raise processor_error(doc, str(e.msg), name) from None
    problems, odd = invalid_terms(quads)
    if not problems and (b"/." in data or b'".' in data):
        try:
            strict = list(ox.parse(data, ox.RdfFormat.JSON_LD, base_iri=base))
        except SyntaxError as e:
            raise processor_error(doc, str(e.msg), name) from None
        if len(strict) != len(quads):
            problems = masked(quads, strict)
    if problems:
        raise dropped_error(doc, problems, name)
    return relabelled(quads, odd) if odd else quads


# -- the program graph ----------------------------------------------------------------------------


def program_graph(quads: list[ox.Quad], name: str) -> tuple[str | None, list[ox.Quad]]:
    """The document's graph IRI (None when it holds only a default graph) and its quads (all of them:
    a document holds one program, one named graph or only the default graph; no copy is made)."""
    names = {q.graph_name for q in quads}
    if any(isinstance(g, ox.BlankNode) for g in names):
        raise JsonLdError("holds a graph named by a blank node; a program graph has an IRI", name)
    named = sorted(g.value for g in names if isinstance(g, ox.NamedNode))
    if len(names) > 1:
        held = ", ".join(["the default graph"] * (len(named) < len(names)) + [f"<{g}>" for g in named])
        raise JsonLdError(f"holds {len(names)} graphs ({held}); load takes one program graph per document "
                          "(export one with --graph)", name)
    if named:
        return named[0], quads
    structures = {t.subject.value for t in quads if t.predicate.value == RDF_TYPE
                  and isinstance(t.object, ox.NamedNode) and t.object.value == P21_NS + "ExchangeStructure"
                  and isinstance(t.subject, ox.NamedNode)}
    return (structures.pop() if len(structures) == 1 else None), quads


def _moved(quads: list[ox.Quad], old: str | None, new: str) -> list[ox.Quad]:
    """``quads`` with the document's graph ``old`` (and every IRI under it) moved to ``new``."""
    if old is None or old == new:
        return quads
    old_prefix, new_prefix = instance_prefix(old), instance_prefix(new)
    graph = ox.NamedNode(new)

    def move(term: Any) -> Any:
        if isinstance(term, ox.NamedNode):
            if term.value == old:
                return graph
            if term.value.startswith(old_prefix):
                return ox.NamedNode(new_prefix + term.value[len(old_prefix):])
        return term

    return [ox.Quad(move(q.subject), q.predicate, move(q.object), graph) for q in quads]


#: the classes of instances kept as their text
_RAW = frozenset({P21_NS + "RawInstance", P21_NS + "UnreadableInstance"})


@lru_cache(maxsize=1)
def _instance_classes() -> frozenset[str]:
    """Every class an instance can have: any edition's entity classes, a raw instance's and an
    unreadable one's (which is raw too; either type alone makes a numbered node an instance)."""
    return frozenset(c for e in EDITIONS for c in edition_plans(e).by_class) | _RAW


class JsonLdLoad:
    """One JSON-LD file's load into the named graph ``source.graph``.

    Everything is read and checked when it is made (so bad input never opens a
    store transaction); the loader's run then writes :meth:`chunks` atomically,
    as for a Part 21 file (:func:`stepnc_graph.loading.loader.load_source`).
    """

    def __init__(self, source: Source, raw: bytes, plans: Plans, progress: Progress | None = None) -> None:
        self.started = time.perf_counter()
        self.source = source
        self.raw = raw
        self.plans = plans
        self.progress = progress
        self.graph = source.graph
        self.result = LoadResult(source.name, source.graph)
        #: none of the derived layer is written with the chunks: derive() finds it all in the store
        self.derived_written: int | None = None
        self.blank_written: int | None = None
        self.derived = True  # whether the load writes a derived layer (see loader.load_source)
        doc = local_contexts(parse_json(raw, source.name), source.name)
        old, quads = program_graph(parse_quads(doc, instance_prefix(source.graph), source.name), source.name)
        self.lines = self._lines(_moved(quads, old, self.graph), doc)
        self.result.triples = len(self.lines)

    @classmethod
    def of_source(cls, source: Source, progress: Progress | None = None) -> "JsonLdLoad":
        """The load of the ``.jsonld`` file ``source``, read and checked: :class:`JsonLdError` (bad
        input: exit 2) when it is not JSON, names a context that would have to be fetched, holds
        several graphs or no instance, or cannot be written back as Part 21."""
        if source.path is None:
            raise JsonLdError("JSON-LD is read from a .jsonld file, not standard input", source.name)
        return cls(source, read_bytes(source.path), iso14649_plans(), progress)

    # what the loader's run asks of a load (stepnc_graph.loading.loader._run)

    def dangling(self, store: Store, where: str) -> list[Diagnostic]:
        """References to unreadable instances: a JSON-LD document has none."""
        return []

    def diagnostics(self) -> list[Diagnostic]:
        return []

    def instances(self, quads: list[ox.Quad]) -> dict[Any, list[str]]:
        """Instance nodes (a class of any edition's schema, or kept raw) and their types.

        A graph read in another edition (``p21:edition``) holds classes the shipped schema does not
        have; they are instances too, or the count would not match the graph's numbered instances."""
        types: dict[Any, list[str]] = defaultdict(list)
        known = _instance_classes()
        for t in quads:
            if t.predicate.value == RDF_TYPE and isinstance(t.object, ox.NamedNode) and t.object.value in known:
                types[t.subject].append(t.object.value)
        return types

    def _plans_of(self, quads: list[ox.Quad]) -> dict[Any, Plans]:
        """The plans each node was read with: its own ``p21:edition``, else its graph's, else the
        shipped edition's (:attr:`plans`)."""
        editions = {t.subject: t.object.value for t in quads
                    if t.predicate.value == P21_NS + "edition" and isinstance(t.object, ox.Literal)}
        default = editions.get(ox.NamedNode(self.graph))

        def plans(edition: str | None) -> Plans:
            return edition_plans(edition) if edition in EDITIONS else self.plans

        shared = plans(default)
        return defaultdict(lambda: shared, {node: plans(e) for node, e in editions.items()})

    def program(self, quads: list[ox.Quad]) -> list[ox.Quad]:
        """The statements kept from the document: all but its load metadata and aliases."""
        g, aliases, activity = self.graph, instance_prefix(self.graph) + "id/", instance_prefix(self.graph) + "load"

        def kept(t: ox.Quad) -> bool:
            s = t.subject.value if isinstance(t.subject, ox.NamedNode) else ""
            if s == g:
                return t.predicate.value not in LOAD_PREDICATES
            return s != activity and not s.startswith(TOOL_IRI) and not (
                s.startswith(aliases) and t.predicate.value == OWL_SAME_AS)

        return [t for t in quads if kept(t)]

    def aliases(self, types: dict[Any, list[str]], program: list[ox.Quad]) -> list[str]:
        """``owl:sameAs`` aliases for unshared its_ids, as a Part 21 load mints them."""
        values: dict[tuple[Any, str], list[Any]] = defaultdict(list)
        for t in program:
            values[(t.subject, t.predicate.value)].append(t.object)
        labels: dict[tuple[str, str], Any] = {}
        plans_of = self._plans_of(program)
        for node, classes in types.items():
            by_class = plans_of[node].by_class
            plans = [by_class[c] for c in classes if c in by_class]
            slots = ([p.slots[p.its_id] for p in plans if p.its_id is not None] if len(plans) == 1
                     else [p.own_slots[p.own_its_id] for p in plans if p.own_its_id is not None])
            for slot in slots:
                for value in values.get((node, slot.prop), []):
                    if isinstance(value, ox.Literal) and value.datatype.value == XSD + "string" and value.value:
                        key = (slot.entity, value.value)
                        labels[key] = None if key in labels else node
        return [f"<{alias_iri(self.graph, scope, label)}> <{OWL_SAME_AS}> {node} .\n"
                for (scope, label), node in sorted(labels.items()) if node is not None]

    def metadata(self, types: dict[Any, list[str]], derived_from: list[Any]) -> list[str]:
        """This load's metadata and provenance (as a Part 21 load writes them)."""
        s, path = f"<{self.graph}>", self.source.path
        now = load_timestamp()
        activity, tool = f"<{instance_prefix(self.graph)}load>", f"<{TOOL_IRI}{__version__}>"
        raw_count = sum(not _RAW.isdisjoint(classes) for classes in types.values())
        where = str(path.resolve()) if path is not None else self.source.name
        out = [f"{s} <{RDF_TYPE}> <{P21_NS}ExchangeStructure> .\n", f"{s} <{RDF_TYPE}> <{PROV}Entity> .\n",
               f"{s} <{DCT}source> {ox.Literal(where)} .\n",
               f"{s} <{P21_NS}byteSize> {_integer(len(self.raw))} .\n",
               f"{s} <{P21_NS}sha256> {ox.Literal(hashlib.sha256(self.raw).hexdigest())} .\n",
               f"{s} <{P21_NS}instanceCount> {_integer(len(types))} .\n",
               f"{s} <{P21_NS}rawInstanceCount> {_integer(raw_count)} .\n",
               f"{s} <{PROV}generatedAtTime> {now} .\n", f"{s} <{PROV}wasGeneratedBy> {activity} .\n",
               f"{activity} <{RDF_TYPE}> <{PROV}Activity> .\n", f"{activity} <{PROV}wasAssociatedWith> {tool} .\n",
               f"{activity} <{PROV}endedAtTime> {now} .\n", f"{tool} <{RDF_TYPE}> <{PROV}SoftwareAgent> .\n",
               f"{tool} <{RDFS}label> {ox.Literal('stepnc-graph ' + __version__)} .\n"]
        if path is not None:
            uri = ox.NamedNode(path.resolve().as_uri())
            out += [f"{s} <{PROV}hadPrimarySource> {uri} .\n", f"{activity} <{PROV}used> {uri} .\n"]
        out += [f"{s} <{PROV}wasDerivedFrom> {source} .\n" for source in derived_from]
        return out

    def _lines(self, quads: list[ox.Quad], doc: Any) -> list[str]:
        """Every triple of the graph to write, as N-Triples lines (duplicates removed); the loader
        adds ``p21:diagnosticCount`` when it commits."""
        types = self.instances(quads)
        if not types:
            raise JsonLdError("holds no STEP-NC instance (no node of a class of the ISO 14649 vocabulary); "
                              "is it a program graph exported by stepnc-graph?", self.source.name)
        program = self.program(quads)
        graph = ox.NamedNode(self.graph)
        earlier = [t.object for t in quads if t.subject == graph
                   and t.predicate.value == PROV + "hadPrimarySource" and isinstance(t.object, ox.NamedNode)]
        self._check_writable(program, doc)
        lines = [f"{t.subject} {t.predicate} {t.object} .\n" for t in program]
        lines += self.aliases(types, program) + self.metadata(types, earlier)
        self.result.instances = self.result.defined = len(types)
        self.result.raw = sum(not _RAW.isdisjoint(classes) for classes in types.values())
        return list(dict.fromkeys(lines))

    def _check_writable(self, program: list[ox.Quad], doc: Any) -> None:
        """Refuse a graph the Part 21 writer cannot write (a value that fits no parameter, a broken
        list, an instance number that is no number)."""
        from stepnc_graph.mapping.writer import WriteError, write_graph

        name = self.source.name
        for q in program:
            what = _NUMBERED.get(q.predicate.value)
            if what is not None and not (isinstance(q.object, ox.Literal) and _WHOLE.fullmatch(q.object.value)):
                value = q.object.value if isinstance(q.object, (ox.Literal, ox.NamedNode, ox.BlankNode)) else ""
                raise JsonLdError(f"cannot be written back as Part 21: {q.subject} has {what[0]} {quote(value)}, "
                                  f"which is no {what[1]} (a whole number)", name,
                                  pointer=pointer(where) if (where := path_of(locate(doc, value, exact=True))) else None)
        try:
            write_graph(self.plans, program, self.graph)
        except WriteError as e:
            raise JsonLdError(f"cannot be written back as Part 21: {e}", name) from None
        except (ValueError, KeyError, IndexError):  # a value the writer does not expect where it is
            raise JsonLdError("cannot be written back as Part 21: the Part 21 writer met a value it cannot place "
                              "(a p21: bookkeeping value edited by hand?); compare the document with an export",
                              name) from None

    def chunks(self) -> Iterator[str]:
        """N-Triples chunks of about CHUNK_TRIPLES lines; the triples of connected blank nodes stay in
        one chunk (a bulk load names blank nodes per call)."""
        parent: dict[str, str] = {}

        def find(x: str) -> str:
            while parent.setdefault(x, x) != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        keys = []
        lines = self.lines
        for line in lines:  # a blank node is the subject or the last term: blanks hold no spaces
            terms = [t for t in (line[:line.index(" ")], line[line.rindex(" ", 0, len(line) - 3) + 1:-3])
                     if t.startswith("_:")]
            if len(terms) == 2:
                parent[find(terms[0])] = find(terms[1])
            keys.append(terms[0] if terms else "")
        groups: dict[str, list[str]] = defaultdict(list)
        for line, key in zip(lines, keys, strict=True):
            groups[find(key) if key else ""].append(line)
        out: list[str] = []
        for group in groups.values():
            out.extend(group)
            if len(out) >= CHUNK_TRIPLES:
                yield "".join(out)
                out.clear()
        if out:
            yield "".join(out)
        if self.progress is not None:
            self.progress(len(self.raw), len(self.raw))


def _integer(value: int) -> str:
    return f'"{value}"^^<{XSD}integer>'
