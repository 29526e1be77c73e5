"""Load Part 21 files into the store: one named graph per file, atomically.

The work is a pipeline of generators -- reader -> mapper -> N-Triples chunks ->
Oxigraph's bulk loader -- so memory follows the file text, not its instances.
"""

from __future__ import annotations

import hashlib
import re
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyoxigraph as ox

from stepnc_graph.core.version import __version__
from stepnc_graph.mapping import ntriples as T
from stepnc_graph.mapping.editions import (decide_edition, edition_plans, group_other_forms, other_fit,
                                             other_form_sentences)
from stepnc_graph.mapping.mapper import DerivedTables, InstanceMapper
from stepnc_graph.mapping.plans import EntityPlan, unread_properties
from stepnc_graph.loading.derive import derive, edition_tables
from stepnc_graph.mapping.plans import (
    P21_DUPLICATE,
    P21_EDITION,
    P21_LINE,
    P21_RAW_TEXT,
    P21_SECTION,
    P21_SYNTAX_ERROR,
    P21_UNREADABLE_TEXT,
)
from stepnc_graph.core.naming import (
    P21_NS,
    TOOL_IRI,
    alias_iri,
    default_graph_iri,
    derived_graph_iri,
    instance_id,
    instance_prefix,
    section_iri,
)
from stepnc_graph.part21.diagnostics import Diagnostic
from stepnc_graph.part21.format import format_header, format_value
from stepnc_graph.part21.reader import Header, Part21Reader, defined_ids
from stepnc_graph.part21.source import decode_source, read_source, read_stdin
from stepnc_graph.core.formats import reads_as
from stepnc_graph.loading.sources import plan_sources, refuse_replacing_other_files
from stepnc_graph.loading.common import DCT, OWL_SAME_AS, PROV, RDFS, LoadResult, Progress, Source, load_timestamp
from stepnc_graph.core.naming import graph_layout
from stepnc_graph.store.contract import Chunk, Companion, Joint, Store
from stepnc_graph.graphs.vocabulary_graph import ensure_vocabulary

if TYPE_CHECKING:
    from stepnc_graph.loading.jsonld import JsonLdLoad

#: A DATA section opener anywhere (files written on one line exist). A match
#: inside a string only adds section triples, which still round-trip; missing
#: a real opener would merge sections on export. The word boundary before it is
#: tested apart (:func:`_data_openers`): a pattern opening with ``\b`` is tried at
#: every offset of the text (0.16 CPU-s for 6 MB), one opening with a literal is not.
_DATA_OPENER = re.compile(r"DATA[ \t\r\n]*[(;]")
_WORD_CHAR = re.compile(r"\w")
#: FILE_SCHEMA names accepted besides the model's own schema names: NIST's
#: merged schema, which holds exactly the schemas stepnc-graph ships.
SCHEMA_ALIASES = {"COMBINED_SCHEMA"}
CHUNK_LINES = 20000
#: derived-layer lines the mapper collects before they go to the store as one companion chunk
#: (~10 MB of text: each chunk is one more bulk-load call, so not many, and not all kept to the end)
DERIVED_CHUNK_LINES = 60000

def _data_openers(text: str) -> int:
    """How many DATA section openers ``text`` holds (``DATA`` not preceded by a word character)."""
    return sum(1 for m in _DATA_OPENER.finditer(text) if m.start() == 0 or not _WORD_CHAR.match(text, m.start() - 1))


def _header_triples(g: str, header: Header) -> list[str]:
    """DCTERMS / p21 triples for the HEADER fields of ISO 10303-21 8.2."""
    s = f"<{g}>"
    out: list[str] = []

    def add(pred: str, value: Any) -> None:
        if isinstance(value, str) and value:
            out.append(f"{s} <{pred}> {T.string(value)} .\n")

    def each(pred: str, value: Any) -> None:
        for v in value if isinstance(value, list) else [value]:
            add(pred, v)

    desc = header.entities.get("FILE_DESCRIPTION") or []
    if desc:
        each(DCT + "description", desc[0])
    if len(desc) > 1:
        add(P21_NS + "implementationLevel", desc[1])
    name = header.entities.get("FILE_NAME") or []
    for i, pred in enumerate([DCT + "title", DCT + "created", DCT + "creator", DCT + "publisher",
                              P21_NS + "preprocessorVersion", P21_NS + "originatingSystem",
                              P21_NS + "authorization"]):
        if i < len(name):
            each(pred, name[i])
    for schema in header.schemas:
        add(P21_NS + "schemaName", schema)
    add(P21_NS + "headerText", header.text)
    if header.repaired:
        add(P21_NS + "repairedHeaderText", format_header(header))
    return out


class _Load:
    """One file's load: holds the reader, the mapper and the running counts.

    ``path`` is the file (None for standard input); ``name`` is what messages
    and the graph's ``dcterms:source`` call it.
    """

    def __init__(self, name: str, path: Path | None, raw: bytes, lenient: bool, graph: str,
                 progress: Progress | None, derived: bool = True, positions: bool = True,
                 edition: str | None = None, reads: frozenset[str] | None = None) -> None:
        self.path = path
        self.name = name
        text, encoding = decode_source(raw, name)
        self.text = text
        self.raw = raw
        self.graph = graph
        self.progress = progress
        self.reader = Part21Reader(text, name, lenient)
        self.reader.diagnostics[:0] = encoding
        prefix = instance_prefix(graph)
        several = _data_openers(text) > 1  # edition 3: instances record their section
        #: the file's edition (``edition``, from ``--edition``, overrides what the file shows)
        self.choice = decide_edition(text, self.reader.header, edition)
        self.mapper = InstanceMapper(edition_plans(self.choice.edition),
                                     lambda i: f"{prefix}i{i}", defined_ids(text),
                                     name, text, (lambda i: section_iri(graph, i + 1)) if several else None,
                                     edition_tables(self.choice.edition) if derived else None,
                                     None if positions else {}, self.other_edition)
        if reads is not None and not derived:  # the derived layer reads every attribute
            self.mapper.hold = unread_properties(self.mapper.plans, reads)
        #: derived-layer triples the mapper wrote into the layer's own chunks (None: none, see derive())
        self.derived_written: int | None = 0
        #: derived-layer lines the mapper wrote with the program's text, as they name its blank
        #: nodes (:class:`Joint`; None: none, see derive())
        self.blank_written: int | None = 0
        self.derived = derived
        self.result = LoadResult(name, graph, edition=self.choice)
        self.known_schemas = {s.upper() for s in self.mapper.plans.model.schemas} | SCHEMA_ALIASES
        self.started = time.perf_counter()

    @classmethod
    def of_file(cls, path: str | Path, lenient: bool, base_iri: str | None, progress: Progress | None,
                edition: str | None = None) -> "_Load":
        """The load of ``path`` into graph ``base_iri`` (default: from the file name)."""
        p = Path(path)
        return cls(str(p), p, read_source(p), lenient, base_iri or default_graph_iri(str(p)), progress,
                   edition=edition)

    def other_edition(self, name: str, count: int) -> tuple[str, EntityPlan, DerivedTables | None, str] | None:
        """Where an instance the file's edition cannot read (``name`` unknown there, or not with
        ``count`` parameters) fits another edition: that edition, its plan and derived tables, and
        what the file's edition has under the name (for the load's report of such instances)."""
        edition = other_fit(self.choice.edition, name, count)
        if edition is None:
            return None
        plan = edition_plans(edition).entities[name.upper()]
        mine = self.mapper.plans.entities.get(name.upper())
        has = "no such entity" if mine is None else f"{len(mine.slots)} ({', '.join(s.name for s in mine.slots)})"
        return edition, plan, edition_tables(edition) if self.derived else None, has

    def chunks(self) -> Iterator[Chunk]:
        out: list[str] = []
        result = self.result
        total = len(self.text)
        derived = self.mapper.derived_lines
        for inst in self.reader.instances():
            self.mapper.map(inst, out)
            result.instances += 1
            if len(out) >= CHUNK_LINES:
                result.triples += len(out)
                yield self.main_chunk("".join(out))
                out.clear()
                if len(derived) >= DERIVED_CHUNK_LINES:
                    yield self.derived_chunk()
                if self.progress:
                    self.progress(inst.end, total)
        if self.needs_held():
            out.extend(self.mapper.held)
        self.mapper.held = []
        out.extend(self.aliases())
        out.extend(self.duplicates())
        out.extend(self.unreadable_texts())
        result.triples += len(out)
        result.raw = self.mapper.raw_count
        result.lists_within_bounds = self.mapper.lists_within_bounds
        result.mandatory_values_set = self.mapper.mandatory_values_set
        result.lines = self.mapper.positions
        result.unreadable = len(self.mapper.unreadable)
        result.unreadable_texts = len(self.reader.unreadable_texts)
        result.defined = self.reader.defined
        result.in_other_editions = group_other_forms(self.mapper.other_forms)
        meta = self.metadata()
        result.triples += len(meta)
        yield self.main_chunk("".join(out) + "".join(meta))
        if derived:
            yield self.derived_chunk()
        if self.progress:
            self.progress(total, total)

    def needs_held(self) -> bool:
        """Whether the lines the mapper held back (attributes the caller does not read, see
        ``load_source``'s ``reads``) are written after all: when the graph has what brings back the
        checks the mapping otherwise guarantees -- a list out of its bounds, an unset mandatory
        attribute or list member -- which read them, or references to instances the reader could
        not read, which the dangling-reference check looks for in every attribute."""
        m = self.mapper
        return bool(m.held) and (not m.lists_within_bounds or not m.mandatory_values_set or m.unset_members
                                 or bool(m.unreadable) or bool(self.missing()))

    def missing(self) -> set[int]:
        """#ids the file names in ``#12=`` only inside a string or unreadable text (edition 3: not
        defined in another file)."""
        external = {int(name[1:]) for name, _ in self.reader.header.references if name.startswith("#")}
        return self.mapper.defined - self.reader.ids - external

    def derived_chunk(self) -> Companion:
        """The derived-layer lines mapped so far, as a chunk for the file's derived graph."""
        lines = self.mapper.derived_lines
        self.derived_written = (self.derived_written or 0) + len(lines)
        chunk = Companion(derived_graph_iri(self.graph), "".join(lines))
        lines.clear()
        return chunk

    def main_chunk(self, text: str) -> str | Joint:
        """The program's ``text`` as a chunk, with the derived-layer lines that name its blank
        nodes (list positions, generic values that are lists or typed values) when it has any:
        one document for the store, so a label names one node in both graphs (see :class:`Joint`)."""
        lines = self.mapper.derived_blank_lines
        if not lines:
            return text
        self.blank_written = (self.blank_written or 0) + len(lines)
        chunk = Joint(text, derived_graph_iri(self.graph), "".join(lines))
        lines.clear()
        return chunk

    def aliases(self) -> list[str]:
        """``owl:sameAs`` links from alias IRIs to instances with an unshared its_id."""
        g = self.graph
        return [f"<{alias_iri(g, scope, label)}> {OWL_SAME_AS} <{target}> .\n"
                for (scope, label), target in sorted(self.mapper.labels.items()) if target is not None]

    def duplicates(self) -> list[str]:
        """Each later definition of an #id (its text and line), on the instance it repeats."""
        subject, text = self.mapper.subject, self.text
        out: list[str] = []
        for k, (i, start, end, line) in enumerate(self.reader.duplicate_texts, start=1):
            node = f"_:dup{k}"  # a node each: two identical later definitions are two triples' worth
            out += [f"<{subject(i)}> {P21_DUPLICATE} {node} .\n",
                    f"{node} {P21_RAW_TEXT} {T.string(text[start:end])} .\n",
                    f"{node} {P21_LINE} {T.integer(line)} .\n"]
        return out

    def unreadable_texts(self) -> list[str]:
        """Text that names no instance (lenient reading), on the graph's node: its text, line and
        syntax error (and its DATA section, in a file with several)."""
        g, text, section = f"<{self.graph}>", self.text, self.mapper.section
        out: list[str] = []
        for k, kept in enumerate(self.reader.unreadable_texts, start=1):
            node = f"_:text{k}"
            out += [f"{g} {P21_UNREADABLE_TEXT} {node} .\n",
                    f"{node} {P21_RAW_TEXT} {T.string(text[kept.start:kept.end])} .\n",
                    f"{node} {P21_LINE} {T.integer(kept.line)} .\n",
                    f"{node} {P21_SYNTAX_ERROR} {T.string(kept.reason)} .\n"]
            if section is not None:
                out.append(f"{node} {P21_SECTION} <{section(kept.section)}> .\n")
        return out

    def metadata(self) -> list[str]:
        g = self.graph
        s = f"<{g}>"
        now = load_timestamp()
        activity = f"<{instance_prefix(g)}load>"
        tool = f"<{TOOL_IRI}{__version__}>"
        used = [f"{activity} <{PROV}used> <{self.path.resolve().as_uri()}> .\n"] if self.path else []
        out = [
            f"{s} {T.RDF_TYPE} <{P21_NS}ExchangeStructure> .\n",
            f"{s} {T.RDF_TYPE} <{PROV}Entity> .\n",
            f"{s} <{DCT}source> {T.string(str(self.path.resolve()) if self.path else self.name)} .\n",
            *([f"{s} <{PROV}hadPrimarySource> <{self.path.resolve().as_uri()}> .\n"] if self.path else []),
            f"{s} <{P21_NS}byteSize> {T.integer(len(self.raw))} .\n",
            f"{s} <{P21_NS}sha256> {T.string(hashlib.sha256(self.raw).hexdigest())} .\n",
            f"{s} <{P21_NS}instanceCount> {T.integer(self.result.instances)} .\n",
            f"{s} <{P21_NS}rawInstanceCount> {T.integer(self.mapper.raw_count)} .\n",
            f"{s} <{PROV}generatedAtTime> {now} .\n",
            f"{s} <{PROV}wasGeneratedBy> {activity} .\n",
            f"{activity} {T.RDF_TYPE} <{PROV}Activity> .\n",
            *used,
            f"{activity} <{PROV}wasAssociatedWith> {tool} .\n",
            f"{activity} <{PROV}endedAtTime> {now} .\n",
            f"{tool} {T.RDF_TYPE} <{PROV}SoftwareAgent> .\n",
            f"{tool} <{RDFS}label> {T.string('stepnc-graph ' + __version__)} .\n",
        ]
        return out + _header_triples(g, self.reader.header) + self.edition3() + self.edition_triples()

    def edition_triples(self) -> list[str]:
        """The file's edition, how it was chosen and the evidence, on the graph's node (the writer
        reads ``p21:edition`` to write the file back in it); the instances read in another edition
        are evidence too, one sentence per edition (each instance also carries its ``p21:edition``)."""
        g, choice = f"<{self.graph}>", self.choice
        evidence = [*choice.evidence, *other_form_sentences(self.result.in_other_editions)]
        return [f"{g} {P21_EDITION} {T.string(choice.edition)} .\n",
                f"{g} <{P21_NS}editionChosenBy> {T.string(choice.chosen_by)} .\n",
                *(f"{g} <{P21_NS}editionEvidence> {T.string(e)} .\n" for e in evidence)]

    def edition3(self) -> list[str]:
        """ANCHOR, REFERENCE, DATA section and SIGNATURE triples (ISO 10303-21:2016, 9-11, 13)."""
        h = self.reader.header
        g, subject = f"<{self.graph}>", self.mapper.subject
        out = [f"{g} <{P21_NS}anchorSectionText> {T.string(h.anchor_text)} .\n"] if h.anchor_text else []
        out += [f"<{subject(i)}> <{P21_NS}anchorName> {T.string(name)} .\n" for name, i in h.anchors]
        if h.reference_text:
            out.append(f"{g} <{P21_NS}referenceSectionText> {T.string(h.reference_text)} .\n")
        out += [f"<{subject(int(name[1:]))}> <{P21_NS}externalReference> {T.typed(uri, T.XSD + 'anyURI')} .\n"
                for name, uri in h.references if name.startswith("#")]
        out += [f"{g} <{P21_NS}signatureText> {T.string(text)} .\n" for text in h.signatures]
        if self.mapper.section is not None:
            for i, text in enumerate(h.data_section_texts):
                sec = f"<{self.mapper.section(i)}>"
                out += [f"{sec} {T.RDF_TYPE} <{P21_NS}DataSection> .\n",
                        f"{sec} <{P21_NS}sectionIndex> {T.integer(i + 1)} .\n"]
                if i < len(h.data_section_repaired) and h.data_section_repaired[i]:
                    # lenient mode read the opener by repairing it: the repaired text is what an
                    # export writes (it must read strictly), the text as read is kept beside it
                    params = h.data_sections[i]
                    repaired = f"DATA({','.join(format_value(v) for v in params)});" if params else "DATA;"
                    out += [f"{sec} <{P21_NS}sectionText> {T.string(repaired)} .\n",
                            f"{sec} <{P21_NS}rawText> {T.string(text)} .\n"]
                else:
                    out.append(f"{sec} <{P21_NS}sectionText> {T.string(text)} .\n")
        return out

    def schema_diagnostics(self) -> list[Diagnostic]:
        unknown = [s for s in self.reader.header.schemas if s not in self.known_schemas]
        return [Diagnostic.make("P21-UNKNOWN-SCHEMA", self.name, 1, 1, None,
                                f"FILE_SCHEMA names {name}, not one of the loaded schemas") for name in unknown]

    def diagnostics(self) -> list[Diagnostic]:
        found = self.schema_diagnostics() + self.reader.diagnostics + self.mapper.diagnostics
        return sorted(found, key=lambda d: (d.line, d.column, d.code))

    def dangling(self, store: Store, where: str) -> list[Diagnostic]:
        """References to instances the reader could not read (lenient mode only), and to ``#id``s
        whose ``#12=`` the file holds only inside a string or unreadable text (the mapper took
        them as defined: it must know the names before reading): from mapped instances (found in
        the graph) and from raw ones (their parsed references)."""
        unreadable = self.mapper.unreadable
        missing = self.missing()
        if not unreadable and not missing:
            return []
        found: set[tuple[int, int, int, int]] = set()  # (line, column, referrer, target)
        for p21_id, line, column, refs in self.mapper.raw_refs:
            found.update((line, column, p21_id, target) for target in refs if target in unreadable or target in missing)
        prefix = instance_prefix(self.graph)
        targets = " ".join(f"(<{prefix}i{t}> {t})" for t in sorted(unreadable | missing))
        positions = self.mapper.positions  # None: the graph holds p21:id and p21:line
        owner = "?owner p21:id ?id ; p21:line ?line ." if positions is None else "FILTER(isIRI(?owner))"
        # From each unreadable instance back to the instances referring to it, directly or
        # through the blank nodes of lists and typed values (SPARQL: it runs on any store).
        rows = store.query(f"""
            PREFIX rdf: <{T.RDF}> PREFIX p21: <{P21_NS}>
            SELECT DISTINCT ?owner ?id ?line ?n WHERE {{ GRAPH {ox.NamedNode(where)} {{
              VALUES (?target ?n) {{ {targets} }}
              {{ ?owner ?p ?target }} UNION {{
                ?cell rdf:first|p21:value ?target .
                ?cell (^rdf:rest|^rdf:first|^p21:value)* ?head .
                ?owner ?p ?head . FILTER(!isBlank(?owner)) }}
              {owner} }} }}""")
        for row in rows:
            if positions is None:
                found.add((int(row["line"].value), 1, int(row["id"].value), int(row["n"].value)))
            elif (ident := instance_id(self.graph, row["owner"].value)) is not None and ident in positions:
                found.add((positions[ident], 1, ident, int(row["n"].value)))
        return [Diagnostic.make("P21-UNRESOLVED-REF", self.name, line, column, p21_id,
                                f"refers to #{target}, which could not be read (see its syntax error)"
                                if target in unreadable else
                                f"refers to #{target}, which is not defined in the file ('#{target}=' occurs only "
                                f"inside a string or text that could not be read)")
                for line, column, p21_id, target in sorted(found)]


def ntriples_chunks(path: str | Path, *, lenient: bool = False, base_iri: str | None = None,
                    edition: str | None = None) -> Iterator[str]:
    """The N-Triples a load of ``path`` writes, in chunks, without a store.

    Everything but the store-dependent last step (the reference check and the
    diagnostic count) and the derived layer; the benchmark uses it to time the
    store on its own.
    """
    for chunk in _Load.of_file(path, lenient, base_iri, None, edition).chunks():
        if isinstance(chunk, Joint):
            yield chunk.text
        elif isinstance(chunk, str):
            yield chunk


def load_source(store: Store, source: Source, *, lenient: bool = False,
                progress: Progress | None = None, derived: bool = True, positions: bool = True,
                edition: str | None = None, reads: frozenset[str] | None = None) -> LoadResult:
    """Load one planned input (:func:`stepnc_graph.loading.sources.plan_sources`): a file or standard input;
    a ``.jsonld`` file is a program graph in JSON-LD (:mod:`stepnc_graph.loading.jsonld`).

    ``derived=False`` writes no derived layer: for a throw-away store that only
    validation reads (shapes see the program graph alone). ``positions=False``
    (Part 21 only) writes no ``p21:id``/``p21:line`` triples and returns the lines
    in :attr:`LoadResult.lines` instead, for the same use. ``edition`` reads a Part 21 file in
    that edition of ISO 14649 (:data:`stepnc_graph.mapping.editions.EDITIONS`) whatever it shows.
    ``reads`` (Part 21, ``derived=False``): the only attribute properties the caller reads, for a
    throw-away graph that only the validator reads; the lines of other attributes are left out
    unless the graph turns out to need them (:meth:`_Load.needs_held`)."""
    if source.path is not None and reads_as(source.path, "jsonld"):
        from stepnc_graph.loading.jsonld import JsonLdLoad

        job: _Load | JsonLdLoad = JsonLdLoad.of_source(source, progress)
        job.derived = derived
        return _run(store, job)
    raw = read_source(source.path) if source.path is not None else read_stdin(name=source.name)
    return _run(store, _Load(source.name, source.path, raw, lenient, source.graph, progress, derived, positions,
                             edition, reads))


def _run(store: Store, job: "_Load | JsonLdLoad") -> LoadResult:
    """Write a prepared load: the file's graph, its derived layer (``<graph>/derived``) and,
    when missing or stale, the store's vocabulary graph, in one atomic load."""
    refuse_graph_name_clashes(store, [job.graph])
    extra: list[Diagnostic] = []

    def before_commit(target: Callable[[str], str]) -> None:
        # The dangling-reference check needs the loaded graph, so the count of
        # diagnostics is the last triple written, inside the same atomic load.
        where = target(job.graph)
        extra.extend(job.dangling(store, where))
        count = len(job.diagnostics()) + len(extra)
        store.add_ntriples(where, f"<{job.graph}> <{P21_NS}diagnosticCount> {T.integer(count)} .\n")
        job.result.triples += 1
        if store.capabilities.persistent:
            # a persistent store (on disk, or remote) always holds the vocabulary; a
            # throw-away one gets it when a query first needs it (query.execute)
            ensure_vocabulary(store, target=target)
        if job.derived:
            job.result.derived_triples = derive(store, job.graph, target, mapped=job.derived_written,
                                                blank_mapped=job.blank_written).triples

    store.replace_graph(job.graph, job.chunks(), before_commit, companions=(derived_graph_iri(job.graph),))
    job.result.diagnostics = sorted(job.diagnostics() + extra, key=lambda d: (d.line, d.column, d.code))
    job.result.seconds = time.perf_counter() - job.started
    return job.result


def load_paths(store: Store, paths: Iterable[str | Path], *, lenient: bool = False, base_iri: str | None = None,
               progress: Progress | None = None, replace: bool = False, derived: bool = True,
               positions: bool = True, edition: str | None = None,
               stdin_graph: str | None = None, reads: frozenset[str] | None = None) -> list[LoadResult]:
    """:func:`stepnc_graph.api.load`: each input into its own named graph, planned first
    (``stdin_graph``: the graph of ``-`` without ``base_iri``, see :func:`plan_sources`)."""
    sources = plan_sources(list(paths), base_iri, stdin_graph)
    store.prepare_to_write()  # the checks below read the newest published state
    refuse_graph_name_clashes(store, [s.graph for s in sources])
    if not replace:
        refuse_replacing_other_files(store, sources)
    return [load_source(store, s, lenient=lenient, progress=progress, derived=derived, positions=positions,
                        edition=edition, reads=reads) for s in sources]


def refuse_graph_name_clashes(store: Store, graphs: Sequence[str]) -> None:
    """:class:`~stepnc_graph.core.naming.GraphNameError` unless programs can be loaded as the graphs
    ``graphs`` (one command's) beside what the store holds: no name of one may be reserved,
    another program's or its companions', or held by a graph that is not its own
    (:meth:`~stepnc_graph.core.naming.GraphLayout.refuse_programs`, from the store's records)."""
    graph_layout(store).refuse_programs(graphs)
