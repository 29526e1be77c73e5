"""`stepnc-graph load | export | unload | info`: Part 21 programs in the store."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import click

from stepnc_graph.cli.common import (
    EXIT_BAD_INPUT,
    EXIT_NONCONFORMING,
    EXIT_OK,
    err,
    open_store,
    out,
    with_store,
)

if TYPE_CHECKING:
    from rich.progress import Progress

    from stepnc_graph.loader import LoadResult
    from stepnc_graph.part21 import Part21SyntaxError
    from stepnc_graph.store import GraphStore


def _progress_bar() -> Progress:
    from rich.progress import BarColumn, DownloadColumn, Progress, TimeRemainingColumn

    return Progress("[progress.description]{task.description}", BarColumn(), DownloadColumn(),
                    TimeRemainingColumn(), console=err, transient=True)


@click.command("load")
@click.argument("files", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False, path_type=Path))
@with_store
@click.option("--lenient", is_flag=True,
              help="Recover from syntax errors instance by instance and report them, instead of stopping.")
@click.option("--base-iri", default=None,
              help="IRI of the file's named graph (instances are <IRI>/i<id>); with several files, a prefix "
                   "to which each file name is added. Default: https://w3id.org/stepnc-graph/data/<file name>.")
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
def load_cmd(files: tuple[Path, ...], store_path: Path | None, memory: bool, lenient: bool,
             base_iri: str | None, fmt: str) -> None:
    """Load Part 21 FILES into the store, one named graph per file.

    Loading a file again replaces its graph; a load that fails leaves the store
    as it was. Schema problems (unknown entity, wrong parameter count or value
    type, unresolved reference) are reported and the instance is kept raw, so
    nothing is lost.

    Exit codes: 0 loaded cleanly, 1 loaded with diagnostics, 2 a file could not
    be loaded (syntax error in strict mode) or bad usage.
    """
    with open_store(store_path, memory) as store:
        results, failures = _load_all(store, files, lenient, base_iri, fmt)
    _report_loads(results, failures, fmt)


def _load_all(store: GraphStore, files: tuple[Path, ...], lenient: bool, base_iri: str | None,
              fmt: str) -> tuple[list[LoadResult], list[Part21SyntaxError]]:
    from stepnc_graph.api import graph_iri_for
    from stepnc_graph.loader import load_file
    from stepnc_graph.part21 import Part21SyntaxError

    results: list[LoadResult] = []
    failures: list[Part21SyntaxError] = []
    for path in files:
        graph = graph_iri_for(path, base_iri, len(files) > 1)
        big = path.stat().st_size > (1 << 20) and err.is_terminal and fmt == "text"
        try:
            if big:
                with _progress_bar() as bar:
                    task = bar.add_task(f"loading {path.name}", total=path.stat().st_size)
                    def advance(done: int, total: int, task: Any = task) -> None:
                        bar.update(task, completed=done, total=total)

                    results.append(load_file(store, path, lenient=lenient, base_iri=graph, progress=advance))
            else:
                results.append(load_file(store, path, lenient=lenient, base_iri=graph))
        except Part21SyntaxError as exc:
            failures.append(exc)
            if fmt == "text":
                err.print(f"[bold red]error:[/] {exc}\n[dim]nothing loaded from {path}; "
                          f"--lenient loads what can be read[/]")
    return results, failures


def _report_loads(results: list[LoadResult], failures: list[Part21SyntaxError], fmt: str) -> NoReturn:
    if fmt == "json":
        doc = {"files": [r.asdict() for r in results], "errors": [e.asdict() for e in failures]}
        click.echo(json.dumps(doc, indent=2))
    else:
        for r in results:
            errors = sum(d.severity == "error" for d in r.diagnostics)
            out.print(f"loaded {r.path} -> {r.graph}\n  {r.instances} instances ({r.raw} kept raw), "
                      f"{r.triples} triples, {len(r.diagnostics)} diagnostics ({errors} errors) in {r.seconds:.2f} s")
            for d in r.diagnostics:
                colour = {"error": "red", "warning": "yellow"}.get(d.severity, "blue")
                ident = f" #{d.p21_id}" if d.p21_id is not None else ""
                out.print(f"  [{colour}]{d.severity}[/] {d.line}:{d.column}{ident} {d.code}: {d.message}",
                          markup=True, highlight=False)
    if failures:
        sys.exit(EXIT_BAD_INPUT)
    sys.exit(EXIT_NONCONFORMING if any(r.diagnostics for r in results) else EXIT_OK)


@click.command("export")
@with_store
@click.option("--graph", default=None, help="The graph to export (see `stepnc-graph info`); default: all, "
                                            "or the only one.")
@click.option("--format", "fmt", type=click.Choice(["ttl", "nt", "nq", "trig", "jsonld", "p21"]), required=True,
              help="p21 writes the graph back as a Part 21 file.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write here instead of standard output.")
def export_cmd(store_path: Path | None, memory: bool, graph: str | None, fmt: str, output: Path | None) -> None:
    """Export one graph or the whole store as RDF or as Part 21."""
    from stepnc_graph.export import ExportError, export

    with open_store(store_path, memory) as store:
        try:
            data = export(store, fmt, graph)
        except ExportError as exc:
            err.print(f"[bold red]error:[/] {exc}")
            sys.exit(EXIT_BAD_INPUT)
    if output is None:
        sys.stdout.buffer.write(data)
        sys.stdout.flush()
    else:
        output.write_bytes(data)
        err.print(f"wrote {output} ({len(data)} bytes)")


@click.command("unload")
@click.argument("graphs", nargs=-1, required=True)
@with_store
def unload_cmd(graphs: tuple[str, ...], store_path: Path | None, memory: bool) -> None:
    """Remove loaded files' graphs (GRAPHS are graph IRIs, see `stepnc-graph info`). Exit 1 if one was absent."""
    from stepnc_graph.api import unload

    with open_store(store_path, memory) as store:
        missing = [g for g in graphs if not unload(store, g)]
    for g in graphs:
        out.print(f"{'not in the store' if g in missing else 'removed'}: {g}")
    sys.exit(EXIT_NONCONFORMING if missing else EXIT_OK)


@click.command("info")
@with_store
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
def info_cmd(store_path: Path | None, memory: bool, fmt: str) -> None:
    """List the graphs in the store with their source file and counts."""
    from stepnc_graph.api import info
    from stepnc_graph.store import default_store_path

    with open_store(store_path, memory) as store:
        rows = info(store)
    if fmt == "json":
        click.echo(json.dumps({"graphs": [r.asdict() for r in rows]}, indent=2))
        return
    out.print(f"{len(rows)} graph(s) in {'memory' if memory else store_path or default_store_path()}")
    for r in rows:
        # one block per graph, IRI on its own line: it is what users copy into --graph / unload
        out.print(f"{r.graph}\n  source {r.source}; {r.instances} instances ({r.raw_instances} raw), "
                  f"{r.triples} triples, {r.diagnostics} diagnostics; loaded {r.loaded}")


