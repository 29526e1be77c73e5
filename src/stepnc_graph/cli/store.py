"""`stepnc-graph load | export | unload | info | compact`: Part 21 programs in the store.

``load``, ``unload`` and ``compact`` write: they take the store's writer lock (another
writer fails with exit 2, or waits with ``--wait``). ``export`` and ``info``
read the last published state: they work during a load, never create a store
and never wait.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import click

from stepnc_graph.core.formats import export_format_names
from stepnc_graph.cli.common import (
    format_choice,
    pick_graph,
    EXIT_BAD_INPUT,
    EXIT_NONCONFORMING,
    EXIT_OK,
    UsageProblem,
    echo_json,
    err,
    error_record,
    escape,
    open_reader,
    open_writer,
    out,
    print_error,
    reports_errors,
    store_option,
    wait_option,
    with_endpoint,
    with_store,
    write_out,
)

if TYPE_CHECKING:
    from rich.progress import Progress

    from stepnc_graph.cli.common import RemoteOptions
    from stepnc_graph.loading.common import LoadResult, Source
    from stepnc_graph.store import Store

_COLOURS = {"error": "red", "warning": "yellow"}


@click.command("load")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(allow_dash=True, path_type=str))
@with_store
@with_endpoint
@wait_option
@click.option("--edition", type=click.Choice(["2002", "fdis2001"]), default=None,
              help="Read the files in this edition of ISO 14649 (2002: the shipped schemas; fdis2001: ISO/FDIS "
                   "14649-10/-11 of 2001) whatever they show; by default each file's FILE_SCHEMA, entity names "
                   "and date decide, and load reports the choice and its evidence.")
@click.option("--lenient", is_flag=True,
              help="Recover from syntax errors instance by instance and report them, instead of stopping.")
@click.option("--base-iri", default=None,
              help="IRI of the file's named graph (instances are <IRI>/i<id>); with several files or a directory, "
                   "a prefix to which each file's name (relative path) is added. Default: "
                   "https://w3id.org/stepnc-graph/data/<file name>. Required for standard input (-).")
@click.option("--replace", is_flag=True,
              help="Replace a graph even when it holds a different file (same name, other folder).")
@click.option("--format", "fmt", type=format_choice(["text", "json"]), default="text", show_default=True)
@reports_errors
def load_cmd(inputs: tuple[str, ...], store_path: Path | None, memory: bool, remote: RemoteOptions, wait: bool,
             lenient: bool, base_iri: str | None, replace: bool, fmt: str, edition: str | None) -> None:
    """Load Part 21 programs into the store, one named graph per file.

    INPUTS are files, directories (every .stp/.step/.p21 file under them,
    named by their path relative to the directory) or - for standard input
    (with --base-iri). Loading a file again replaces its graph; a load that
    fails leaves the store as it was. Schema problems (unknown entity, wrong
    parameter count or value type, unresolved reference) are reported and the
    instance is kept raw, so nothing is lost. The summary ends with the
    store's size on disk (--format json: disk_bytes; null in memory or at an
    endpoint).

    Exit codes: 0 loaded cleanly, 1 loaded with diagnostics, 2 a file could not
    be loaded (syntax error in strict mode, unreadable) or bad usage.
    """
    from stepnc_graph.loading.loader import refuse_graph_name_clashes
    from stepnc_graph.loading.sources import plan_sources, refuse_replacing_other_files
    from stepnc_graph.store import directory_bytes

    sources = plan_sources(inputs, base_iri)
    with open_writer(store_path, memory, wait, remote) as store:
        refuse_graph_name_clashes(store, [s.graph for s in sources])
        if not replace:
            refuse_replacing_other_files(store, sources)
        results, failures = _load_all(store, sources, lenient, fmt, edition)
        location, own_files = _location(store), _has_own_files(store)
    # measured once the store is closed: closing flushes its last writes to disk (about 1 MB for
    # the shipped example), so a size taken while it was open fell short of what `du` then shows
    size = directory_bytes(Path(location)) if own_files else None
    _report_loads(results, failures, fmt, location, size)


def _has_own_files(store: Store) -> bool:
    """Whether the store keeps files of its own: not in memory, and not an endpoint, which manages
    its own storage."""
    return store.capabilities.persistent and store.maintenance() is not None


def human_bytes(count: int) -> str:
    """A size for people, in decimal units as disk tools state them: 812 B, 12.3 MB, 1.4 GB."""
    size = float(count)
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if size < 1000 or unit == "TB":
            return f"{count:,} B" if unit == "B" else f"{size:,.1f} {unit}"
        size /= 1000
    raise AssertionError("unreachable")


def _load_all(store: Store, sources: list[Source], lenient: bool,
              fmt: str, edition: str | None = None) -> tuple[list[LoadResult], list[BaseException]]:
    """Load each source in turn; a file that fails is reported and the others go on."""
    from stepnc_graph.cli.common import user_errors
    from stepnc_graph.loading.loader import load_source

    results: list[LoadResult] = []
    failures: list[BaseException] = []
    sizes = [_size(s) for s in sources]
    with _progress(sum(sizes), fmt) as bar:
        task = bar.add_task("loading", total=sum(sizes)) if bar is not None else None
        done = 0
        for source, size in zip(sources, sizes, strict=True):
            def advance(position: int, total: int, base: int = done, size: int = size,
                        name: str = escape(Path(source.name).name)) -> None:
                if bar is not None and task is not None:  # once read, the derived layer and publishing remain
                    label = f"loading {name}" if position < total else f"{name}: derived layer, publishing"
                    bar.update(task, completed=base + position * size // max(total, 1), description=label)

            try:
                results.append(load_source(store, source, lenient=lenient, progress=advance, edition=edition))
            except user_errors() as exc:
                failures.append(exc)
                if fmt == "text":
                    hint = (f"nothing loaded from {source.name}; --lenient loads what can be read"
                            if getattr(exc, "recoverable", False) and not lenient
                            else f"nothing loaded from {source.name}")
                    print_error(exc, hint)
            done += size
    return results, failures


def _n(count: int | None) -> str:
    """A count with thousands separators (``?`` when the load did not record it)."""
    return "?" if count is None else f"{count:,}"


def _size(source: Source) -> int:
    try:
        return source.path.stat().st_size if source.path is not None else 0
    except OSError:
        return 0


class _NoBar:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None


def _progress(total: int, fmt: str) -> Any:
    """A progress bar over all files (bytes read), on a terminal, for loads worth one."""
    if total < (1 << 20) or fmt != "text" or not err.is_terminal:
        return _NoBar()
    from rich.progress import DownloadColumn

    return _bar(DownloadColumn())


def _bar(counter: Any) -> Progress:
    """A transient rich progress bar on stderr: description, bar, ``counter``, time left."""
    from rich.progress import BarColumn, TimeRemainingColumn
    from rich.progress import Progress as RichProgress

    return RichProgress("[progress.description]{task.description}", BarColumn(), counter, TimeRemainingColumn(),
                        console=err, transient=True)


def _report_loads(results: list[LoadResult], failures: list[BaseException], fmt: str, location: str,
                  size: int | None) -> NoReturn:
    """Each file's summary, then the store's size on disk (where it has one), and the exit code."""
    from stepnc_graph.mapping.editions import other_form_sentences  # loaded with the files already

    if fmt == "json":
        echo_json({"files": [r.asdict() for r in results], "errors": [error_record(e) for e in failures],
                   "store": location, "disk_bytes": size})
    else:
        for r in results:
            errors = sum(d.severity == "error" for d in r.diagnostics)
            raw = f" ({r.raw:,} kept raw{f', {r.unreadable:,} unreadable' if r.unreadable else ''})"
            rate = f" ({r.instances / r.seconds:,.0f} instances/s)" if r.seconds > 0 and r.instances >= 1000 else ""
            out.print(f"loaded {escape(r.path)} -> {escape(r.graph)}\n  {r.instances:,} instances{raw}, "
                      f"{r.triples:,} triples, {len(r.diagnostics):,} diagnostics ({errors:,} errors) in "
                      f"{r.seconds:.2f} s{rate}")
            if r.edition is not None:
                mixed = "".join(f"; {s}" for s in other_form_sentences(r.in_other_editions))
                out.print(f"  edition {r.edition.edition} (chosen by {r.edition.chosen_by}: "
                          f"{escape('; '.join(r.edition.evidence) or 'no evidence')}){escape(mixed)}")
            for d in r.diagnostics:
                ident = f" #{d.p21_id}" if d.p21_id is not None else ""
                out.print(f"  [{_COLOURS.get(d.severity, 'blue')}]{d.severity}[/] {d.line}:{d.column}{ident} "
                          f"{d.code}: {escape(d.message)}")
        if size is not None:
            out.print(f"store {escape(location)}: {human_bytes(size)} on disk")
    if failures:
        sys.exit(EXIT_BAD_INPUT)
    sys.exit(EXIT_NONCONFORMING if any(r.diagnostics for r in results) else EXIT_OK)


@click.command("export")
@store_option
@with_endpoint
@click.option("--graph", default=None, help="The graph to export (see `stepnc-graph info`). Default: the loaded "
                                            "graphs -- programs and link graphs, not the vocabulary or derived "
                                            "layers -- for nq, trig and jsonld; the only program for ttl, nt, p21.")
@click.option("--format", "fmt", type=format_choice(export_format_names()),
              required=True, help="p21 writes the graph back as a Part 21 file; jsonld-tree frames a program as a "
                                  "tree (project, workplans, workingsteps, operation, tool, feature).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write here instead of standard output.")
@reports_errors
def export_cmd(store_path: Path | None, remote: RemoteOptions, graph: str | None, fmt: str,
               output: Path | None) -> None:
    """Export one graph or the store's loaded graphs as RDF or as Part 21.

    Without --graph every format exports the same graphs: the programs, their
    link graphs and graphs you added -- never the vocabulary graph or the
    derived layers, which a load writes again (name one with --graph to export
    it). ttl, nt and p21 hold one graph: without --graph the store must hold one
    program. Exports are deterministic: the same graph gives the same bytes. Exit 2 for
    a graph that is not in the store or an output that cannot be written.
    """
    from stepnc_graph.exporting.exporter import export

    if output is not None and not output.parent.is_dir():
        raise UsageProblem(f"-o {output}: the directory {output.parent} does not exist")
    with open_reader(store_path, remote) as store:
        data = export(store, fmt, pick_graph(store, graph) if graph is not None else None)
    if output is None:
        try:
            write_out(data, uchar=fmt != "p21")
        except OSError as e:
            raise UsageProblem(f"cannot write the export to standard output: {e.strerror or e}") from None
    else:
        _write_output(output, data)
        err.print(f"wrote {escape(str(output))} ({len(data)} bytes)")


def _write_output(output: Path, data: bytes) -> None:
    """Write ``data`` to the file ``output``; a failure (a full disk, ``/dev/full``) names the file
    and the cause, and a file cut short by it is removed: it must not pass for an export."""
    try:
        fh = open(output, "wb")
    except OSError as e:
        raise UsageProblem(f"-o {output}: cannot write the export: {e.strerror or e}") from None
    try:
        with fh:
            fh.write(data)
    except OSError as e:
        cut = f"-o {output}: cannot write the export: {e.strerror or e}"
        try:
            if output.is_file():
                output.unlink()
                cut += " (the part written was removed)"
        except OSError:
            cut += " (the part written is still there)"
        raise UsageProblem(cut) from None


@click.command("unload")
@click.argument("graphs", nargs=-1, required=True)
@store_option
@with_endpoint
@wait_option
@click.option("--compact", is_flag=True,
              help="Compact the database now, whatever was deleted since its last compaction.")
@reports_errors
def unload_cmd(graphs: tuple[str, ...], store_path: Path | None, remote: RemoteOptions, wait: bool,
               compact: bool) -> None:
    """Remove loaded files' graphs (GRAPHS are graph IRIs, see `stepnc-graph info`, or a unique end
    of one: the file name, shaft.stp).

    A program goes with its derived layer and its link graphs; a link graph
    (<program>/links/<name>) goes alone. The vocabulary graph and a derived
    layer on its own are refused. Removing the only program gives its disk
    space back at once. Beside other programs, deleted data keeps its space
    until the database is compacted, and a compaction rewrites the whole
    store, so unload compacts once the data deleted since the last compaction
    reaches a third of the store (`info` shows how much waits); `--compact`
    compacts now. Exit 2 if a graph is not in the store or is refused (the
    others are still removed).
    """
    from stepnc_graph.api import unload
    from stepnc_graph.core.naming import GraphNameError

    problems: dict[str, Exception] = {}
    with open_writer(store_path, wait=wait, remote=remote, create=False) as store:
        named: dict[str, str] = {}
        for g in graphs:
            try:
                named[g] = pick_graph(store, g)
            except UsageProblem as exc:
                problems[g] = exc
        last = next((named[g] for g in reversed(graphs) if g in named), None)  # one compaction, at the end
        for g, iri in named.items():
            try:
                if not unload(store, iri, compact=compact and iri == last):
                    problems[g] = UsageProblem(f"no graph {iri} in the store (see `stepnc-graph info`)")
            except GraphNameError as exc:
                problems[g] = exc
    for g in graphs:
        if g not in problems:
            out.print(f"removed: {escape(named[g])}")
    if problems:
        for problem in problems.values():
            print_error(problem)
        sys.exit(EXIT_BAD_INPUT)


@click.command("compact")
@store_option
@wait_option
@click.option("--format", "fmt", type=format_choice(["text", "json"]), default="text", show_default=True)
@reports_errors
def compact_cmd(store_path: Path | None, wait: bool, fmt: str) -> None:
    """Give back the disk space that unloaded programs still hold.

    `unload` compacts the database's indexes once enough was deleted (or with
    `--compact`), but Oxigraph keeps the strings (literals, IRIs) that only the
    removed data used, so a store whose programs come and go grows. This
    rebuilds the database from the graphs it holds, as one atomic write
    (readers keep reading the state before it). It copies every quad: minutes
    for a store of many large programs. Never creates a store.
    """
    from stepnc_graph.api import compact

    with open_writer(store_path, wait=wait, create=False) as store, _quad_progress(fmt) as bar:
        task = bar.add_task("compacting", total=None) if bar is not None else None

        def advance(done: int, total: int) -> None:
            if bar is not None and task is not None:
                bar.update(task, completed=done, total=total)

        result = compact(store, advance)
        location = _location(store)
    if fmt == "json":
        echo_json({"store": location, **result.asdict()})
        return
    out.print(f"compacted {escape(location)}: {result.before / 1e6:,.0f} MB -> {result.after / 1e6:,.0f} MB on "
              f"disk ({result.quads:,} quads)")


def _location(store: Store) -> str:
    """Where a store is, for users: its absolute directory, its endpoint, or "memory"."""
    return store.location


def _quad_progress(fmt: str) -> Any:
    """A progress bar over quads copied, on a terminal."""
    if fmt != "text" or not err.is_terminal:
        return _NoBar()
    from rich.progress import MofNCompleteColumn

    return _bar(MofNCompleteColumn())


@click.command("info")
@store_option
@with_endpoint
@click.option("--format", "fmt", type=format_choice(["text", "json"]), default="text", show_default=True)
@reports_errors
def info_cmd(store_path: Path | None, remote: RemoteOptions, fmt: str) -> None:
    """List the loaded files' graphs in the store, with their source file and counts."""
    from stepnc_graph.api import info

    with open_reader(store_path, remote) as store:
        rows = info(store)
        location = _location(store)
        maintenance = store.maintenance()  # None: an endpoint manages its own storage
        deleted = maintenance.deleted_quads if maintenance is not None else None
    if fmt == "json":
        echo_json({"store": location, "graphs": [r.asdict() for r in rows], "deleted_quads": deleted})
        return
    out.print(f"{len(rows)} graph(s) in {escape(location)}")
    if deleted:
        out.print(f"{deleted:,} deleted quads hold disk space until the next compaction "
                  f"(`unload --compact`, `compact`, or an unload once they reach a third of the store)")
    for r in rows:
        # one block per graph, IRI on its own line: it is what users copy into --graph / unload
        out.print(f"{escape(r.graph)}\n  source {escape(str(r.source))}; {_n(r.instances)} instances "
                  f"({_n(r.raw_instances)} raw), {_n(r.triples)} triples, {_n(r.diagnostics)} diagnostics; "
                  f"loaded {r.loaded}")
        if r.edition is not None:
            out.print(f"  edition {escape(r.edition)} (chosen by {escape(str(r.edition_chosen_by))}: "
                      f"{escape('; '.join(r.edition_evidence) or 'no evidence')})")
