"""Validate Part 21 programs -- or any RDF data -- against the generated shapes, the process rules
and your own.

    import stepnc_graph as sg
    report = sg.validate(["part.stp"])                 # load into a throw-away store, then check
    report = sg.validate(store, graphs=[graph_iri])   # or check what a store holds
    report = sg.validate(["data.ttl"], extra_shapes=["shapes.ttl"], iso_shapes=False)  # any RDF, any shapes
    print(report.conforms, report.passes, report.to_text())

Shapes come from ``shapes/`` (generated ``*.ttl`` and the hand-written
``shapes/process/*.ttl``; left out with ``iso_shapes=False``) plus any
``extra_shapes`` files; they are compiled once per process (:mod:`.engine`)
and run by the store. Loader diagnostics of the files loaded here are results
too (severity Violation).
"""

from __future__ import annotations

import re
import tempfile
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError, option
from stepnc_graph.core.naming import DATA_BASE, P21_NS, instance_id, program_graphs
from stepnc_graph.store.contract import Store, is_store
from stepnc_graph.part21.diagnostics import Diagnostic
from stepnc_graph.validation import compiled
from stepnc_graph.validation import components as C
from stepnc_graph.validation.compiled import CompiledShapesWarning
from stepnc_graph.validation.engine import SHAPES_GRAPH, Check, Row, refuse_service, run
from stepnc_graph.validation.rdfdata import DataError, RdfLoad, load_rdf, rdf_format
from stepnc_graph.validation.editions import edition_rules
from stepnc_graph.validation.report import SEVERITIES, Result, ValidationReport
from stepnc_graph.validation.shapes import (
    RDF_FIRST,
    RDF_TYPE,
    SH,
    IllFormedShapes,
    ShapesError,
    ShapesGraph,
    UnsupportedShapes,
    literal_text,
    sh,
)

if TYPE_CHECKING:  # the loader is imported only when a file is validated
    from stepnc_graph.loading.common import LoadResult

__all__ = ["CompiledShapes", "CompiledShapesWarning", "DataError", "IllFormedShapes", "Result", "ShapesError",
           "UnsupportedShapes", "ValidationError", "ValidationReport", "shape_files", "validate"]


class ValidationError(StepncGraphError, ValueError):
    """A validation asked in a way it cannot run: an unknown severity, a graph the store does not hold."""

SHAPES_NS = "https://w3id.org/stepnc-graph/shapes#"
STEPNC_NS = "https://w3id.org/stepnc-graph/iso14649#"
RDFS_LABEL = "<http://www.w3.org/2000/01/rdf-schema#label>"
RDFS_COMMENT = "<http://www.w3.org/2000/01/rdf-schema#comment>"
#: loader codes a shape re-checks (reported once, by the shape)
COVERED_BY_SHAPES = {"P21-ABSTRACT"}


def shape_files(shapes_dir: Path | None = None, process: bool = True) -> list[Path]:
    """The shipped shapes: generated files, then the process rules."""
    if shapes_dir is None:
        from stepnc_graph.core.resources import shapes_dir as default

        shapes_dir = default()
    files = sorted(shapes_dir.glob("*.ttl"))
    if process:
        files += sorted((shapes_dir / "process").glob("*.ttl"))
    return files


class CompiledShapes:
    """The checks of a set of shape files, and their shapes graph, read on first use and only as far
    as needed: describing a result reads the files its check names (:attr:`Check.files`); finding
    none reads no file at all. ``hierarchy``: the data files' subclasses and typed individuals
    (class -> nodes), which the checks' class tests expand to."""

    def __init__(self, files: Sequence[Path], checks: tuple[Check, ...], graph: ShapesGraph | None = None,
                 hierarchy: tuple[dict[str, set[str]], dict[str, set[str]]] | None = None,
                 data_positions: frozenset[int] = frozenset()) -> None:
        self.files = tuple(files)
        self.checks = checks
        self._graph = graph  # every file, when the shapes were compiled here
        self._partial = ShapesGraph()
        self._read: set[int] = set()
        self.data_positions = data_positions
        if hierarchy is None and graph is not None:
            hierarchy = ({k: set(v) for k, v in graph.subclasses.items()},
                         {k: {i for i in v if i.startswith("<")} for k, v in graph.instances.items()})
        self.hierarchy = hierarchy or ({}, {})

    @property
    def graph(self) -> ShapesGraph:
        """The graph of every file."""
        return self.describing(range(len(self.files)))

    def describing(self, positions: Iterable[int]) -> ShapesGraph:
        """A graph holding (at least) the files at ``positions``: blank nodes are named by file
        position, so it names them as the compiled checks do."""
        if self._graph is not None:
            return self._graph
        for position in sorted(set(positions) - self._read):
            self._partial.add_file(self.files[position], position, data=position in self.data_positions)
            self._read.add(position)
        if len(self._read) == len(self.files):
            self._graph = self._partial
        return self._partial


@lru_cache(maxsize=8)
def _compiled(files: tuple[tuple[str, float], ...], directory: str) -> CompiledShapes:
    paths = [Path(name) for name, _mtime in files]
    try:
        texts = [p.read_bytes() for p in paths]
    except OSError as exc:
        raise ShapesError(f"{exc.filename}: {exc.strerror or exc}") from None
    names = compiled.relative_names(paths, Path(directory))
    data = frozenset(i for i, p in enumerate(paths) if _is_support(p, Path(directory)))
    if names is not None:
        shipped = Path(directory) / compiled.CACHE_FILE
        try:
            text = shipped.read_text(encoding="utf-8")
            checks, hierarchy = compiled.loads(text, compiled.digest(list(zip(names, texts, strict=True))))
            return CompiledShapes(paths, checks, hierarchy=hierarchy, data_positions=data)
        except (OSError, compiled.StaleChecks) as exc:
            if paths == shape_files(Path(directory)):  # the shipped set itself: say why it is not used
                reason = exc.strerror if isinstance(exc, OSError) else str(exc)
                warnings.warn(f"{shipped} is not used: {reason}. Compiling the shapes instead (about 0.2 s); "
                              f"`stepnc-graph ontology build` refreshes the file.", CompiledShapesWarning,
                              stacklevel=2)
    try:
        decoded = [(str(p), t.decode("utf-8")) for p, t in zip(paths, texts, strict=True)]
    except UnicodeDecodeError as exc:
        raise ShapesError(f"shapes are not UTF-8: {exc}") from None
    graph, compiled_checks = compiled.compile_texts(decoded, data)
    return CompiledShapes(paths, tuple(compiled_checks), graph, data_positions=data)


def _is_support(path: Path, directory: Path) -> bool:
    """Whether ``path`` is the shipped ``support.ttl``: part of the data graph, not of the shapes."""
    try:
        return path.resolve() == (directory / compiled.SUPPORT_FILE).resolve()
    except OSError:
        return False


def compile_shapes(files: Sequence[Path], directory: Path | None = None) -> CompiledShapes:
    """The checks of shapes files: the shipped compiled ones when ``files`` are the files they were
    compiled from (in ``directory``, default the shipped shapes), else compiled here; cached per
    process while the files are unchanged."""
    for f in files:
        if not f.is_file():
            raise ShapesError(f"{f}: no such shapes file")
    if directory is None:
        from stepnc_graph.core.resources import shapes_dir

        directory = shapes_dir()
    return _compiled(tuple((str(f), f.stat().st_mtime) for f in files), str(directory))


def validate(source: object, *, graphs: Sequence[str] | None = None, extra_shapes: Sequence[str | Path] = (),
             severity: str = "Info", lenient: bool = True, process: bool = True,
             shapes_dir: Path | None = None, iso_shapes: bool = True,
             allow_service: bool = False, edition: str | None = None,
             progress: Callable[[str], None] | None = None) -> ValidationReport:
    """Validate files (loaded into a throw-away store) or graphs of a store.

    ``source`` is a :class:`~stepnc_graph.store.GraphStore`, a
    :class:`~stepnc_graph.store.remote.RemoteStore` (whose graphs are copied into
    memory and checked here) or an iterable of paths: Part 21 programs, JSON-LD
    program graphs, or any RDF file (``.ttl``, ``.nt``, ``.nq``, ``.trig``,
    ``.rdf``: :mod:`.rdfdata`). ``iso_shapes=False`` leaves out the shipped
    shapes (then ``extra_shapes`` are the shapes graph: a general SHACL
    validator). ``severity`` is the lowest severity reported. Raises
    :class:`ShapesError` for unreadable or refused shapes, :class:`DataError`
    for an RDF file that does not parse and, with ``lenient=False``,
    :class:`~stepnc_graph.part21.Part21SyntaxError` for a Part 21 file that does not parse. A shape whose SPARQL has a ``SERVICE``
    clause is refused (ShapesError) unless ``allow_service``. ``edition`` reads every Part 21 file in
    that edition of ISO 14649 (default: each file's own); the rules applied are its edition's
    (:mod:`.editions`). ``progress(phase)`` hears what a long run is doing (loading with the share
    read, checking a graph, describing its results).
    """
    phase = progress or (lambda text: None)
    started = time.perf_counter()
    files = (shape_files(shapes_dir, process) if iso_shapes else []) + [Path(p) for p in extra_shapes]
    if not files:
        raise ShapesError(f"no shapes: give {option('shapes', 'FILE', api='extra_shapes')}, or leave the ISO 14649 "
                          "shapes in")
    compiled_shapes = compile_shapes(files, shapes_dir)
    shapes, checks = compiled_shapes, compiled_shapes.checks
    level = severity.capitalize()
    if level not in SEVERITIES:
        raise ValidationError(f"severity must be one of {', '.join(s.lower() for s in SEVERITIES)}")
    refuse_service(list(checks), allow_service)  # before any file is loaded or graph copied
    needs_shapes = any(f"<{SHAPES_GRAPH}>" in c.query for c in checks)
    if is_store(source) and source.capabilities.local_reads:
        if needs_shapes and source.capabilities.persistent:
            raise UnsupportedShapes("a SPARQL constraint reading $shapesGraph runs on files, not on a store "
                                    "validated in place")
        if needs_shapes:
            _add_shapes_graph(source.oxigraph, shapes)
        report = _validate_store(source, graphs, shapes, list(checks), {}, phase=phase)
    elif is_store(source):  # reads are requests: the graphs are copied here and checked
        targets = list(graphs) if graphs is not None else program_graphs(source)
        phase(f"copying {len(targets):,} graph(s) from the endpoint")
        with source.local_copy(targets) as copy:
            if needs_shapes:
                _add_shapes_graph(copy.oxigraph, shapes)
            report = _validate_store(copy, targets, shapes, list(checks), {}, phase=phase)
    else:
        report = _validate_files([Path(p) for p in source], shapes, list(checks), lenient, needs_shapes,  # type: ignore[attr-defined]
                                 iso_shapes, edition, phase)
    report.seconds = time.perf_counter() - started
    return report.at_least(level)


def _validate_files(paths: list[Path], shapes: CompiledShapes, checks: list[Check], lenient: bool,
                    needs_shapes: bool, iso_shapes: bool, edition: str | None = None,
                    phase: Callable[[str], None] = lambda text: None) -> ValidationReport:
    """Load the files into a throw-away store (Part 21 by the loader, and JSON-LD program graphs
    when the ISO shapes run; other RDF by :mod:`.rdfdata`) and check each file's graph."""
    from stepnc_graph.loading.loader import load_paths as load
    from stepnc_graph.loading.sources import STDIN_GRAPH

    rdf = [p for p in paths if rdf_format(p, programs=iso_shapes) is not None and not p.is_dir()]
    programs = [p for p in paths if p not in rdf]
    with throwaway_store(paths) as store:
        if needs_shapes:
            _add_shapes_graph(store.oxigraph, shapes)
        # shapes read the program graph only; positions come from the load unless a check reads them
        def read(position: int, total: int) -> None:
            phase(f"loading {len(programs):,} file(s): {100 * position // max(total, 1)} %")

        loaded = load(store, programs, lenient=lenient, derived=False, positions=_reads_positions(checks),
                      edition=edition, progress=read, stdin_graph=STDIN_GRAPH) if programs else []
        diagnostics = {r.graph: r.diagnostics for r in loaded}
        # graphs this call's Part 21 mapping wrote, where the checks it guarantees are skipped
        mapped = {r.graph: r for r in loaded if not r.path.lower().endswith(".jsonld")}
        data = [load_rdf(store.oxigraph, p, _rdf_graph(p, {r.graph for r in loaded})) for p in rdf]
        order = {str(p): i for i, p in enumerate(paths)}
        graphs = sorted([(order.get(r.path, 0), r.graph) for r in loaded] + [(order[str(d.path)], d.graph) for d in data])
        return _validate_store(store, [g for _, g in graphs], shapes, checks, diagnostics, mapped,
                               {d.graph: d for d in data}, phase)


def _rdf_graph(path: Path, taken: set[str]) -> str:
    """The graph an RDF data file is validated in: named by its file, as a program's is."""
    from urllib.parse import quote

    graph = DATA_BASE + quote(path.name, safe="")
    n = 2
    while graph in taken:
        graph = f"{DATA_BASE}{quote(path.name, safe='')}-{n}"
        n += 1
    taken.add(graph)
    return graph


def _add_shapes_graph(store: ox.Store, shapes: CompiledShapes) -> None:
    """The shapes files as the named graph ``$shapesGraph`` stands for (SHACL 5.3.1)."""
    from stepnc_graph.validation.shapes import base_iri

    target = ox.NamedNode(SHAPES_GRAPH)
    for f in shapes.files:
        try:
            store.extend([ox.Quad(t.subject, t.predicate, t.object, target)
                          for t in ox.parse(path=str(f), format=ox.RdfFormat.TURTLE, base_iri=base_iri(str(f)))])
        except (SyntaxError, OSError) as exc:
            raise ShapesError(f"{f}: {exc}") from None


#: ``p21:id`` or ``p21:line`` in a query, as a full IRI or prefixed (any prefix: erring on the side of keeping them)
_POSITION_TERM = re.compile(r"(?:p21#|:)(?:id|line)\b")


def _reads_positions(checks: Sequence[Check]) -> bool:
    """Whether a check (an organisation's own SPARQL, say) may read ``p21:id``/``p21:line``: it
    names them, reads any predicate (a variable in predicate position), or is ``sh:closed``. Then
    the throw-away graph keeps those triples; otherwise their lines come from the load (a sixth
    fewer triples to insert; 100k instances, end to end, medians in one quiet hour: 4.2 s with
    them, 3.5-3.8 s without)."""
    return any(_POSITION_TERM.search(c.query) or c.constraint == "closed"
               or (c.sparql_node is not None and _ANY_PREDICATE.search(_PROJECTION.sub("SELECT ", c.query)))
               for c in checks)


#: a triple pattern whose predicate is a variable (after the subject, a variable or an IRI)
_ANY_PREDICATE = re.compile(r"(?:[?$]\w+|<[^>\s]*>)\s+[?$]\w+\s+(?:[?$]\w+|<[^>\s]*>|\"|_:|\[|\d)")
#: a SELECT's projection (``SELECT DISTINCT ?this ?item ?dim``: three variables, no triple pattern)
_PROJECTION = re.compile(r"\bSELECT\b[^{]*?(?=\bWHERE\b|\{)", re.IGNORECASE)


#: Input above this size is validated in a temporary on-disk store instead of memory: Oxigraph's
#: in-memory store holds about 70 bytes of RAM per byte of Part 21 (measured: 1M instances, 63 MB,
#: peaked at 4.4 GB), its on-disk store keeps a bounded cache. Below it, memory is faster (100k
#: instances, 6 MB: 3.6 s against 5.7 s to load).
MEMORY_VALIDATION_BYTES = 16_000_000


def _input_bytes(paths: Sequence[str | Path]) -> int:
    """The size of the files to validate, as the load will find them (standard input counts 0)."""
    from stepnc_graph.loading.sources import STDIN_GRAPH, plan_sources

    return sum(s.path.stat().st_size for s in plan_sources(list(paths), stdin_graph=STDIN_GRAPH)
               if s.path is not None)


@contextmanager
def throwaway_store(paths: Sequence[str | Path]) -> Iterator[Any]:
    """An in-memory store for the files ``paths``, or a temporary on-disk one when they are large."""
    from stepnc_graph.store import open_store

    if _input_bytes(paths) <= MEMORY_VALIDATION_BYTES:
        with open_store(memory=True) as store:
            yield store
        return
    with tempfile.TemporaryDirectory(prefix="stepnc-graph-validate-") as tmp:
        with open_store(Path(tmp) / "store", readonly=False) as store:  # written through .oxigraph
            yield store


def _implied_skips(store: ox.Store, loaded: LoadResult) -> frozenset[str]:
    """What the Part 21 mapping guarantees in the graph it wrote (:mod:`.implied`)."""
    from stepnc_graph.mapping.plans import P21_UNSET
    from stepnc_graph.validation import implied

    unset_member = store.query(f"ASK {{ ?cell {RDF_FIRST} {P21_UNSET} }}",
                               default_graph=ox.NamedNode(loaded.graph))
    return frozenset({implied.ALWAYS} | (set() if unset_member else {implied.NO_UNSET_MEMBERS})
                     | ({implied.LIST_BOUNDS} if loaded.lists_within_bounds else set())
                     | ({implied.MANDATORY_SET} if loaded.mandatory_values_set else set()))


def _validate_store(store: Store, graphs: Sequence[str] | None, shapes: CompiledShapes, checks: list[Check],
                    diagnostics: dict[str, list[Diagnostic]], mapped: Mapping[str, LoadResult] | None = None,
                    data: Mapping[str, RdfLoad] | None = None,
                    phase: Callable[[str], None] = lambda text: None) -> ValidationReport:
    targets = list(graphs) if graphs is not None else program_graphs(store)
    results: list[Result] = []
    ran = 0
    oxstore: ox.Store = store.oxigraph
    for graph in targets:
        if not oxstore.contains_named_graph(ox.NamedNode(graph)):
            raise ValidationError(f"no graph {graph} in the store")
        loaded = mapped.get(graph) if mapped else None  # written by this call's Part 21 mapping
        phase(f"checking {_short_graph(graph)}: {len(checks):,} checks")
        rows, n = run(oxstore, graph, checks, _implied_skips(oxstore, loaded) if loaded else frozenset(),
                      shapes.hierarchy, allow_service=True)  # validate() refused what it must before
        ran += n
        phase(f"describing {len(rows):,} result(s) of {_short_graph(graph)}")
        describer = _Describer(oxstore, graph, shapes, loaded.lines if loaded else None)
        results += edition_rules(oxstore, graph, describer.results(rows))
        if data and graph in data:
            results += [_ill_typed_result(graph, bad) for bad in data[graph].ill_typed]
        elif graph in diagnostics:
            results += [_diagnostic_result(graph, d) for d in diagnostics[graph] if d.code not in COVERED_BY_SHAPES]
        else:
            results += describer.raw_instances()
    results.sort(key=lambda r: r.sort_key)
    return ValidationReport(results, targets, ran)


def _short_graph(graph: str) -> str:
    """A graph's last path segment, for progress lines."""
    return graph.rstrip("/").rsplit("/", 1)[-1] or graph


def _ill_typed_result(graph: str, bad: object) -> Result:
    from stepnc_graph.validation.rdfdata import IllTyped

    assert isinstance(bad, IllTyped)
    lexical = literal_text(bad.literal)
    datatype = bad.literal.rsplit("^^", 1)[-1]
    return Result("Violation", graph, bad.subject.strip("<>"), None, None, None, _readable_path(bad.predicate), lexical,
                  f"{lexical!r} is not a valid {_local(datatype)} literal", None, None, "loader:RDF-ILL-TYPED",
                  path_iri=bad.predicate, value_term=bad.literal, focus_term=bad.subject)


def _diagnostic_result(graph: str, d: Diagnostic) -> Result:
    from stepnc_graph.core.naming import instance_iri

    focus = instance_iri(graph, d.p21_id) if d.p21_id is not None else graph
    return Result("Violation", graph, focus, d.p21_id, None, d.line, None, None, d.message, d.code,
                  "ISO 10303-21", f"loader:{d.code}")


def _readable_path(path: str) -> str:
    """``<...#entity.attr>/<...#e2.attr2>`` as ``attr/attr2``: attribute names, other IRIs by local name."""
    text = re.sub(rf"<{re.escape(STEPNC_NS)}[^.>]*\.([^>]*)>", r"\1", path)
    text = re.sub(r"<[^>]*[#/]([^>#/]*)>", r"\1", text)
    return text[1:-1] if text.startswith("(") and text.endswith(")") and text.count("(") == 1 else text


#: component IRI -> component, for default messages
_COMPONENTS: dict[str, C.Component] = {comp.iri: comp for comp in C.REGISTRY}


def _severity(term: str) -> str:
    """sh:Violation, sh:Warning, sh:Info by name; any other severity IRI in full (SHACL 2.1.6)."""
    iri = term.strip("<>")
    return iri[len(SH):] if iri.startswith(SH) and iri[len(SH):] in SEVERITIES else iri


def _preferred(messages: Sequence[str]) -> str:
    """The message to show: one without a language tag, else English, else the first."""
    if not messages:
        return ""
    plain = [m for m in messages if m.endswith('"') or '"^^' in m]
    english = [m for m in messages if re.search(r'"@en(-[A-Za-z]+)?$', m)]
    return literal_text((plain or english or list(messages))[0])


def _local(term: str) -> str:
    """A readable name for a term: the local name of a vocabulary IRI."""
    if term.startswith("<") and term.endswith(">"):
        iri = term[1:-1]
        for ns in (STEPNC_NS, SHAPES_NS, P21_NS, SH, "http://www.w3.org/2001/XMLSchema#"):
            if iri.startswith(ns):
                return iri[len(ns):]
        return iri
    return term


class _Describer:
    """Turns raw rows into results: Part 21 #id, line and entity of focus nodes and values, messages.

    ``lines`` (#id -> line) stands in for the ``p21:id``/``p21:line`` triples of a
    graph loaded without them (:attr:`~stepnc_graph.loading.loader.LoadResult.lines`)."""

    def __init__(self, store: ox.Store, graph: str, shapes: CompiledShapes,
                 lines: Mapping[int, int] | None = None) -> None:
        self.store = store
        self.graph = graph
        self.shapes = shapes
        self.lines = lines
        self.info: dict[str, tuple[int | None, int | None, str | None]] = {}
        self._g: ShapesGraph | None = None

    @property
    def g(self) -> ShapesGraph:
        return self._g if self._g is not None else self.shapes.graph

    def lookup(self, terms: Iterable[str]) -> None:
        """#id, line and entity name of instance IRIs, in one query."""
        wanted = sorted({t for t in terms if t.startswith("<") and t not in self.info})
        for start in range(0, len(wanted), 2000):
            found = self._positions(wanted[start:start + 2000])
            for key, (ident, line, types) in found.items():
                self.info[key] = (ident, line, "+".join(sorted(types)) or None)

    def _positions(self, terms: list[str]) -> dict[str, tuple[int, int, list[str]]]:
        """#id, line and type names of the instance IRIs among ``terms`` (``<iri>`` texts)."""
        g = ox.NamedNode(self.graph)
        found: dict[str, tuple[int, int, list[str]]] = {}
        if self.lines is None:
            rows = self.store.query(f"SELECT ?s ?id ?line ?t WHERE {{ VALUES ?s {{ {' '.join(terms)} }} ?s <{P21_NS}id> ?id ; "
                                    f"<{P21_NS}line> ?line . OPTIONAL {{ ?s a ?t }} }}", default_graph=g)
            for r in rows:  # type: ignore[union-attr]
                entry = found.setdefault(str(r[0]), (int(r[1].value), int(r[2].value), []))
                if r[3] is not None:
                    entry[2].append(_local(str(r[3])))
            return found
        for term in terms:
            ident = instance_id(self.graph, term[1:-1])
            if ident is not None and ident in self.lines:
                found[term] = (ident, self.lines[ident], [])
        if found:
            rows = self.store.query(f"SELECT ?s ?t WHERE {{ VALUES ?s {{ {' '.join(found)} }} ?s a ?t }}",
                                    default_graph=g)
            for r in rows:  # type: ignore[union-attr]
                found[str(r[0])][2].append(_local(str(r[1])))
        return found

    def owner(self, node: ox.BlankNode) -> str | None:
        """The instance holding a blank node (a list cell or typed value)."""
        current: object = node
        g = ox.NamedNode(self.graph)
        for _ in range(10000):
            holder = next(iter(self.store.quads_for_pattern(None, None, current, g)), None)  # type: ignore[arg-type]
            if holder is None:
                return None
            current = holder.subject
            if isinstance(current, ox.NamedNode):
                return str(current)
        return None

    def results(self, rows: list[Row]) -> list[Result]:
        self._g = self.shapes.describing({p for r in rows for p in r.check.files}) if rows else None
        focus_terms = {str(r.focus) if not isinstance(r.focus, ox.BlankNode) else self.owner(r.focus) or "" for r in rows}
        self.lookup(focus_terms | {str(r.value) for r in rows if isinstance(r.value, ox.NamedNode)})
        return [self.result(r) for r in rows]

    def result(self, row: Row) -> Result:
        c = row.check
        focus = str(row.focus)
        where = self.owner(row.focus) if isinstance(row.focus, ox.BlankNode) else focus
        ident, line, entity = self.info.get(where or "", (None, None, None))
        shape = c.shape
        labels = (shape, c.parent) if c.parent else (shape,)
        clause = next((literal_text(v) for s in labels if (v := self.g.value(s, f"<{P21_NS}isoClause>"))), None)
        value = self.describe(row.value) if row.value is not None else None
        path_sparql: str | None
        path_term: str | None
        if row.path is not None:  # sh:closed, or a SPARQL solution's ?path
            path_sparql = path_term = str(row.path)
        else:
            path_sparql, path_term = c.path, c.path_term
        path = _readable_path(path_sparql) if path_sparql else None
        messages = self.messages(row, value)
        return Result(
            severity=_severity(c.severity), graph=self.graph, focus=focus.strip("<>"), p21_id=ident, entity=entity,
            line=line, path=path, value=value, message=_preferred(messages), rule=self.rule(c),
            clause=clause, component=c.component.strip("<>"), shape=shape.strip("<>") if shape.startswith("<") else None,
            path_iri=path_sparql,
            value_term=str(row.value) if row.value is not None else None,
            focus_term=focus, shape_term=shape, path_term=path_term,
            path_turtle=self.path_turtle(path_term) if path_term else None, message_terms=tuple(messages))

    def path_turtle(self, term: str, depth: int = 0) -> str:
        """A SHACL path node of the shapes graph written as Turtle (blank nodes nested)."""
        if not term.startswith("_:") or depth > 20:
            return term
        if self.g.value(term, RDF_FIRST) is not None:
            return "( " + " ".join(self.path_turtle(t, depth + 1) for t in self.g.items(term)) + " )"
        parts = [f"{p} {self.path_turtle(o, depth + 1)}" for p in self.g.predicates(term) for o in self.g.objects(term, p)]
        return "[ " + " ; ".join(parts) + " ]"

    def describe(self, value: object) -> str:
        text = str(value)
        if isinstance(value, ox.Literal):
            return value.value
        if text in self.info:
            ident, _, entity = self.info[text]
            return f"#{ident} {(entity or '').upper()}".strip()
        if isinstance(value, ox.BlankNode):
            return "a list or typed value"
        return _local(text)

    def rule(self, c: Check) -> str | None:
        for s in (c.shape, c.parent):
            if s is None:
                continue
            label = self.g.value(s, f"<{SHAPES_NS}rule>")
            text = self.g.value(s, f"<{SHAPES_NS}expressText>")
            name = self.g.value(s, RDFS_LABEL)
            if label and text and name:
                return f"{literal_text(name)}: {literal_text(text)}"
            kind = self.g.value(s, f"<{P21_NS}expressType>")
            if name and kind:
                return f"{literal_text(name)} : {literal_text(kind)}"
            if name:
                return literal_text(name)
        return None

    def messages(self, row: Row, value: str | None) -> list[str]:
        """The result's messages as literals (N-Triples): the SPARQL constraint's or validator's
        sh:message, else the shape's (SHACL 2.1.5), ``{$var}``/``{?var}`` replaced by the
        solution's bindings or the component's parameters; else the component's own text."""
        c = row.check
        for s in (c.sparql_node, c.shape):
            own = self.g.objects(s, sh("message")) if s else []
            if own:
                return [self.fill(m, row) for m in own]
        args = dict(c.args)
        component = _COMPONENTS.get(c.component.strip("<>"))
        text = component.message(self.g, args, value, c.shape) if component is not None and args else \
            f"{_local(c.component)} not satisfied{f', found {value}' if value is not None else ''}"
        return ['"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"']

    def fill(self, message: str, row: Row) -> str:
        """``{$name}`` and ``{?name}`` in a message literal replaced by the value they name."""
        values: dict[str, str] = {"this": str(row.focus)}
        if row.value is not None:
            values["value"] = str(row.value)
        if row.path is not None:
            values["path"] = str(row.path)
        values.update(row.check.args)
        values.update((k, str(v)) for k, v in row.bindings)

        def sub(m: re.Match[str]) -> str:
            term = values.get(m.group(1))
            if term is None:
                return m.group(0)
            shown = literal_text(term) if term.startswith('"') else term.strip("<>")
            return shown.replace("\\", "\\\\").replace('"', '\\"')

        return re.sub(r"\{[$?]([A-Za-z_][\w]*)\}", sub, message)

    def raw_instances(self) -> list[Result]:
        """Instances the loader kept raw (a store validated without its load's diagnostics)."""
        rows = self.store.query(
            f"SELECT ?s ?id ?line ?name WHERE {{ ?s {RDF_TYPE} <{P21_NS}RawInstance> ; <{P21_NS}id> ?id ; "
            f"<{P21_NS}line> ?line . OPTIONAL {{ ?s <{P21_NS}entityName> ?name }} }}",
            default_graph=ox.NamedNode(self.graph))
        out = []
        for r in rows:  # type: ignore[union-attr]
            name = r[3].value if r[3] is not None else None
            out.append(Result("Violation", self.graph, r[0].value, int(r[1].value), name, int(r[2].value), None,
                              None, "kept raw by the loader: it does not fit the schema (load it again to see why)",
                              "P21 raw instance", "ISO 10303-21", "loader:P21-RAW"))
        return out
