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
too, of the diagnostic's own severity (an error a Violation, a warning a Warning).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError, option
from stepnc_graph.core.naming import program_graphs
from stepnc_graph.part21.diagnostics import Diagnostic
from stepnc_graph.store.contract import Store, is_store
from stepnc_graph.validation.compiled import CompiledShapes, CompiledShapesWarning, compile_shapes, shape_files
from stepnc_graph.validation.describe import Describer, diagnostic_result, ill_typed_result
from stepnc_graph.validation.editions import edition_notes, edition_rules
from stepnc_graph.validation.engine import SHAPES_GRAPH, Check
from stepnc_graph.validation.runner import refuse_service, run
from stepnc_graph.validation.rdfdata import DataError, RdfLoad, load_rdf, rdf_format
from stepnc_graph.validation.report import SEVERITIES, Result, ValidationReport
from stepnc_graph.validation.shapes import RDF_FIRST, IllFormedShapes, ShapesError, UnsupportedShapes
from stepnc_graph.validation.throwaway import (add_shapes_graph, input_bytes, properties_kept, rdf_graph,
                                               throwaway_store)

if TYPE_CHECKING:  # the loader is imported only when a file is validated
    from stepnc_graph.loading.common import LoadResult

__all__ = ["CompiledShapes", "CompiledShapesWarning", "DataError", "IllFormedShapes", "Result", "ShapesError",
           "UnsupportedShapes", "ValidationError", "ValidationReport", "compile_shapes", "shape_files",
           "throwaway_store", "validate"]


class ValidationError(StepncGraphError, ValueError):
    """A validation asked in a way it cannot run: an unknown severity, a graph the store does not hold."""


#: loader codes a shape re-checks (reported once, by the shape)
COVERED_BY_SHAPES = {"P21-ABSTRACT"}


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
            add_shapes_graph(source.oxigraph, shapes)
        report = _validate_store(source, graphs, shapes, list(checks), {}, phase=phase)
    elif is_store(source):  # reads are requests: the graphs are copied here and checked
        targets = list(graphs) if graphs is not None else program_graphs(source)
        phase(f"copying {len(targets):,} graph(s) from the endpoint")
        with source.local_copy(targets) as copy:
            if needs_shapes:
                add_shapes_graph(copy.oxigraph, shapes)
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
    size = input_bytes(paths)
    with throwaway_store(paths, size) as store:
        if needs_shapes:
            add_shapes_graph(store.oxigraph, shapes)
        # shapes read the program graph only; positions come from the load unless a check reads them
        def read(position: int, total: int) -> None:
            phase(f"loading {len(programs):,} file(s): {100 * position // max(total, 1)} %")

        read(0, 1)
        # the attributes no check reads are left out where that pays (throwaway.properties_kept)
        reads = properties_kept(store, shapes, size)
        loaded = load(store, programs, lenient=lenient, derived=False, positions=shapes.reads_positions(),
                      edition=edition, progress=read, stdin_graph=STDIN_GRAPH, reads=reads) if programs else []
        diagnostics = {r.graph: r.diagnostics for r in loaded}
        # graphs this call's Part 21 mapping wrote, where the checks it guarantees are skipped
        mapped = {r.graph: r for r in loaded if not r.path.lower().endswith(".jsonld")}
        data = [load_rdf(store.oxigraph, p, rdf_graph(p, {r.graph for r in loaded})) for p in rdf]
        order = {str(p): i for i, p in enumerate(paths)}
        graphs = sorted([(order.get(r.path, 0), r.graph) for r in loaded] + [(order[str(d.path)], d.graph) for d in data])
        return _validate_store(store, [g for _, g in graphs], shapes, checks, diagnostics, mapped,
                               {d.graph: d for d in data}, phase)


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
    notes: list[str] = []
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
        describer = Describer(oxstore, graph, shapes, loaded.lines if loaded else None)
        results += edition_rules(oxstore, graph, describer.results(rows), shapes.files)
        notes += edition_notes(oxstore, graph, shapes.files)
        if data and graph in data:
            results += [ill_typed_result(graph, bad) for bad in data[graph].ill_typed]
        elif graph in diagnostics:
            results += [diagnostic_result(graph, d) for d in diagnostics[graph] if d.code not in COVERED_BY_SHAPES]
        else:
            results += describer.raw_instances()
    results.sort(key=lambda r: r.sort_key)
    return ValidationReport(results, targets, ran, notes=notes)


def _short_graph(graph: str) -> str:
    """A graph's last path segment, for progress lines."""
    return graph.rstrip("/").rsplit("/", 1)[-1] or graph


