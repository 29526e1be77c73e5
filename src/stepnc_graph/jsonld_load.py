"""Load a JSON-LD document of a program graph (what ``export --format jsonld`` wrote, maybe
edited by a PLM system) as that program's named graph, so that the Part 21 export gives the
program back.

**No network, ever.** A JSON-LD processor fetches every context named by an IRI
(``"@context": "https://..."``, ``@import``, a scoped context given as a string),
which would let a document make stepnc-graph open connections or read local
files. Before the document reaches the processor, every context in it is
checked: the shipped context's IRI (:data:`~stepnc_graph.naming.CONTEXT_IRI`)
is replaced by the installed ``ontology/context.jsonld``, any other IRI is
refused with an error naming it. A JSON-LD processor therefore never sees a
context it would have to fetch. The processor is rdflib's (a dependency
already; its JSON-LD 1.1 support parses every export, type-scoped contexts and
lists of lists included, which the tests check against the store).

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
import stat
import time
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph import __version__
from stepnc_graph.loader import DCT, PROV, RDFS, LoadResult, Progress, load_time
from stepnc_graph.mapping.plan import Plans, iso14649_plans
from stepnc_graph.naming import CONTEXT_IRI, P21_NS, TOOL_IRI, alias_iri, instance_prefix
from stepnc_graph.part21.diagnostics import Diagnostic
from stepnc_graph.sources import Source, SourceError
from stepnc_graph.store import Store

SUFFIXES = (".jsonld",)
RDF_TYPE = "http://www.w3.org/1999/02/22-rdf-syntax-ns#type"
XSD = "http://www.w3.org/2001/XMLSchema#"
OWL_SAME_AS = "http://www.w3.org/2002/07/owl#sameAs"
#: what the graph says about its load: replaced by this load's values
LOAD_PREDICATES = frozenset({
    DCT + "source", PROV + "hadPrimarySource", P21_NS + "byteSize", P21_NS + "sha256", P21_NS + "instanceCount",
    P21_NS + "rawInstanceCount", P21_NS + "diagnosticCount", PROV + "generatedAtTime", PROV + "wasGeneratedBy"})
CHUNK_TRIPLES = 20000


class JsonLdError(SourceError):
    """A JSON-LD input that cannot be loaded: not JSON, a remote context, not one program graph, ..."""

    def __init__(self, message: str, file: str, line: int | None = None, column: int | None = None) -> None:
        where = f"{file}:{line}:{column}" if line is not None else file
        super().__init__(f"{where}: {message}")
        self.file, self.line, self.column, self.message = file, line, column, message

    def asdict(self) -> dict[str, Any]:
        return {"type": "JsonLdError", "file": self.file, "line": self.line, "column": self.column,
                "message": self.message}


def is_jsonld(path: Path | str) -> bool:
    """Whether a load input is read as JSON-LD (by its name: ``.jsonld``, any case)."""
    return Path(path).suffix.lower() in SUFFIXES


# -- reading the document -------------------------------------------------------------------------


def read_bytes(path: Path) -> bytes:
    """The file's bytes; devices and directories are refused (they would never end)."""
    mode = path.stat().st_mode
    if stat.S_ISDIR(mode):
        raise IsADirectoryError(f"{path}: a directory, not a JSON-LD file")
    if not (stat.S_ISREG(mode) or stat.S_ISFIFO(mode)):
        raise OSError(f"{path}: not a regular file (a device or socket); give a JSON-LD file")
    return path.read_bytes()


def parse_json(raw: bytes, name: str) -> Any:
    """The JSON value of ``raw``; :class:`JsonLdError` with line and column where it is not JSON."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = raw.count(b"\n", 0, e.start) + 1
        column = e.start - (raw.rfind(b"\n", 0, e.start) + 1) + 1
        raise JsonLdError(f"not UTF-8 (byte 0x{raw[e.start]:02X}); JSON-LD is UTF-8", name, line, column) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise JsonLdError(f"not JSON: {e.msg}", name, e.lineno, e.colno) from None
    except RecursionError:
        raise JsonLdError("not JSON that can be read: nested too deeply", name) from None


def local_contexts(doc: Any, name: str) -> Any:
    """``doc`` with every context named by an IRI resolved without the network.

    The shipped context's IRI becomes the installed context; any other IRI -- in
    ``@context`` anywhere (documents, nodes, scoped term definitions) or in
    ``@import`` -- is refused: a JSON-LD processor would fetch it.
    """
    shipped: Any = None
    stack = [doc]
    while stack:
        value = stack.pop()
        if value is shipped:  # the shipped context, put in place: nothing to resolve in it
            continue
        if isinstance(value, list):
            stack.extend(value)
            continue
        if not isinstance(value, dict):
            continue
        for key in ("@context", "@import"):
            if key not in value:
                continue
            entries = value[key] if isinstance(value[key], list) else [value[key]]
            resolved = []
            for entry in entries:
                if isinstance(entry, str):
                    if entry != CONTEXT_IRI:
                        raise JsonLdError(
                            f"{key} {entry!r} names a context stepnc-graph would have to fetch; it never fetches "
                            f"contexts: put the context in the document, or name the shipped one, {CONTEXT_IRI}",
                            name)
                    if shipped is None:
                        from stepnc_graph.jsonld import shipped_context

                        shipped = shipped_context().source
                    entry = shipped if key == "@context" else {"@context": shipped}
                resolved.append(entry)
            if key == "@import" and resolved:  # an @import'ed context is inlined where it is imported
                del value["@import"]
                for entry in resolved:
                    for k, v in (entry.get("@context", entry) if isinstance(entry, dict) else {}).items():
                        value.setdefault(k, v)
            else:
                value[key] = resolved if isinstance(value[key], list) else resolved[0]
        stack.extend(value.values())
    return doc


def parse_quads(doc: Any, base: str, name: str) -> list[ox.Quad]:
    """The quads of a JSON-LD document whose contexts are all local (see :func:`local_contexts`)."""
    from rdflib import Dataset
    from rdflib.parser import PythonInputSource

    dataset = Dataset()
    try:
        dataset.parse(PythonInputSource(doc), format="json-ld", base=base)
        text = dataset.serialize(format="nquads")
    except Exception as e:  # rdflib's JSON-LD errors have no common base class
        raise JsonLdError(f"not JSON-LD that can be read: {type(e).__name__}: {e}", name) from None
    return list(ox.parse(text.encode("utf-8"), ox.RdfFormat.N_QUADS))


def named_graph_of(path: Path) -> str | None:
    """The graph a JSON-LD file names, if it is readable and names one: what it is loaded as
    without ``--base-iri``. That is the top-level ``@id`` of a graph's export, or the ``@id`` of
    the one named graph of a whole-store export; relative to ``@base``. Errors are left to the load."""
    try:
        doc = json.loads(read_bytes(path).decode("utf-8-sig"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(doc, dict):
        return None
    bases = _bases(doc)
    if not isinstance(doc.get("@id"), str):
        inner = doc.get("@graph")
        if not (isinstance(inner, list) and len(inner) == 1 and isinstance(inner[0], dict)):
            return None
        doc = inner[0]
        bases += _bases(doc)
    if not isinstance(doc.get("@id"), str) or "@graph" not in doc:
        return None
    from urllib.parse import urljoin

    iri = urljoin(bases[-1], doc["@id"]) if bases else str(doc["@id"])
    try:
        ox.NamedNode(iri)
    except ValueError:
        return None
    return iri


def _bases(node: dict[str, Any]) -> list[str]:
    """The ``@base`` values of a node's own (inline) contexts, in order."""
    contexts = node.get("@context")
    return [c["@base"] for c in (contexts if isinstance(contexts, list) else [contexts])
            if isinstance(c, dict) and isinstance(c.get("@base"), str)]


# -- the program graph ----------------------------------------------------------------------------


def program_graph(quads: list[ox.Quad], name: str) -> tuple[str | None, list[ox.Triple]]:
    """The document's graph IRI (None when it holds only a default graph) and its triples.

    A document holds one program: one named graph, or only the default graph.
    """
    graphs: dict[str | None, list[ox.Triple]] = defaultdict(list)
    for q in quads:
        if isinstance(q.graph_name, ox.BlankNode):
            raise JsonLdError("holds a graph named by a blank node; a program graph has an IRI", name)
        graphs[q.graph_name.value if isinstance(q.graph_name, ox.NamedNode) else None].append(q.triple)
    named = sorted(g for g in graphs if g is not None)
    if len(named) > 1 or (named and None in graphs):
        held = ", ".join(f"<{g}>" if g else "the default graph" for g in sorted(graphs, key=lambda g: g or ""))
        raise JsonLdError(f"holds {len(graphs)} graphs ({held}); load takes one program graph per document "
                          "(export one with --graph)", name)
    if named:
        return named[0], graphs[named[0]]
    triples = graphs.get(None, [])
    structures = {t.subject.value for t in triples if t.predicate.value == RDF_TYPE
                  and isinstance(t.object, ox.NamedNode) and t.object.value == P21_NS + "ExchangeStructure"
                  and isinstance(t.subject, ox.NamedNode)}
    return (structures.pop() if len(structures) == 1 else None), triples


def _mover(old: str | None, new: str) -> Any:
    """The IRI map moving the document's graph ``old`` (and everything under it) to ``new``."""
    if old is None or old == new:
        return lambda term: term
    old_prefix, new_prefix = instance_prefix(old), instance_prefix(new)

    def move(term: Any) -> Any:
        if isinstance(term, ox.NamedNode):
            if term.value == old:
                return ox.NamedNode(new)
            if term.value.startswith(old_prefix):
                return ox.NamedNode(new_prefix + term.value[len(old_prefix):])
        return term

    return move


class JsonLdLoad:
    """One JSON-LD file's load into the named graph ``source.graph``.

    Everything is read and checked when it is made (so bad input never opens a
    store transaction); the loader's run then writes :meth:`chunks` atomically,
    as for a Part 21 file (:func:`stepnc_graph.loader.load_source`).
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
        self.derived = True  # whether the load writes a derived layer (see loader.load_source)
        doc = local_contexts(parse_json(raw, source.name), source.name)
        old, triples = program_graph(parse_quads(doc, instance_prefix(source.graph), source.name), source.name)
        move = _mover(old, self.graph)
        self.triples = [ox.Triple(move(t.subject), t.predicate, move(t.object)) for t in triples]
        self.lines = self._lines()
        self.result.triples = len(self.lines)

    @classmethod
    def of_source(cls, source: Source, progress: Progress | None = None) -> "JsonLdLoad":
        """The load of the ``.jsonld`` file ``source``, read and checked: :class:`JsonLdError` (bad
        input: exit 2) when it is not JSON, names a context that would have to be fetched, holds
        several graphs or no instance, or cannot be written back as Part 21."""
        if source.path is None:
            raise JsonLdError("JSON-LD is read from a .jsonld file, not standard input", source.name)
        return cls(source, read_bytes(source.path), iso14649_plans(), progress)

    # what the loader's run asks of a load (stepnc_graph.loader._run)

    def dangling(self, store: Store, where: str) -> list[Diagnostic]:
        """References to unreadable instances: a JSON-LD document has none."""
        return []

    def diagnostics(self) -> list[Diagnostic]:
        return []

    def instances(self) -> dict[Any, list[str]]:
        """Instance nodes (a class of the schema, or kept raw) and their types."""
        types: dict[Any, list[str]] = defaultdict(list)
        for t in self.triples:
            if t.predicate.value == RDF_TYPE and isinstance(t.object, ox.NamedNode) and (
                    t.object.value in self.plans.by_class or t.object.value == P21_NS + "RawInstance"):
                types[t.subject].append(t.object.value)
        return types

    def program(self) -> list[ox.Triple]:
        """The triples kept from the document: all but its load metadata and aliases."""
        g, aliases, activity = self.graph, instance_prefix(self.graph) + "id/", instance_prefix(self.graph) + "load"

        def kept(t: ox.Triple) -> bool:
            s = t.subject.value if isinstance(t.subject, ox.NamedNode) else ""
            if s == g:
                return t.predicate.value not in LOAD_PREDICATES
            return s != activity and not s.startswith(TOOL_IRI) and not (
                s.startswith(aliases) and t.predicate.value == OWL_SAME_AS)

        return [t for t in self.triples if kept(t)]

    def aliases(self, types: dict[Any, list[str]], program: list[ox.Triple]) -> list[str]:
        """``owl:sameAs`` aliases for unshared its_ids, as a Part 21 load mints them."""
        values: dict[tuple[Any, str], list[Any]] = defaultdict(list)
        for t in program:
            values[(t.subject, t.predicate.value)].append(t.object)
        labels: dict[tuple[str, str], Any] = {}
        for node, classes in types.items():
            plans = [self.plans.by_class[c] for c in classes if c in self.plans.by_class]
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
        now = f'"{load_time().isoformat(timespec="seconds")}"^^<{XSD}dateTime>'
        activity, tool = f"<{instance_prefix(self.graph)}load>", f"<{TOOL_IRI}{__version__}>"
        raw_count = sum(P21_NS + "RawInstance" in classes for classes in types.values())
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

    def _lines(self) -> list[str]:
        """Every triple of the graph to write, as N-Triples lines (duplicates removed); the loader
        adds ``p21:diagnosticCount`` when it commits."""
        types = self.instances()
        if not types:
            raise JsonLdError("holds no STEP-NC instance (no node of a class of the ISO 14649 vocabulary); "
                              "is it a program graph exported by stepnc-graph?", self.source.name)
        program = self.program()
        earlier = [t.object for t in self.triples if t.subject == ox.NamedNode(self.graph)
                   and t.predicate.value == PROV + "hadPrimarySource" and isinstance(t.object, ox.NamedNode)]
        self._check_writable(program)
        lines = [f"{t.subject} {t.predicate} {t.object} .\n" for t in program]
        lines += self.aliases(types, program) + self.metadata(types, earlier)
        self.result.instances = self.result.defined = len(types)
        self.result.raw = sum(P21_NS + "RawInstance" in classes for classes in types.values())
        return list(dict.fromkeys(lines))

    def _check_writable(self, program: list[ox.Triple]) -> None:
        """Refuse a graph the Part 21 writer cannot write (a value that fits no parameter, a broken list)."""
        from stepnc_graph.mapping.writer import WriteError, write_graph

        g = ox.NamedNode(self.graph)
        try:
            write_graph(self.plans, (ox.Quad(t.subject, t.predicate, t.object, g) for t in program), self.graph)
        except (WriteError, ValueError, KeyError, IndexError) as e:
            raise JsonLdError(f"cannot be written back as Part 21: {e}", self.source.name) from None

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
