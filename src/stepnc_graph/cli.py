"""The ``stepnc-graph`` command line. The only module that prints.

Exit codes, for scripts: 0 ok; 1 the data does not conform (a stale
generated file, incomplete coverage); 2 bad input or usage (syntax or schema
errors, unknown options).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NoReturn, TypeVar

import click
from rich.console import Console
from rich.progress import BarColumn, DownloadColumn, Progress, TimeRemainingColumn
from rich.table import Table

from stepnc_graph import __version__
from stepnc_graph.express import ExpressSyntaxError, parse_file
from stepnc_graph.express.parser import ParsedSchema
from stepnc_graph.resources import data_root
from stepnc_graph.schema import SchemaError, SchemaErrors, build_model

if TYPE_CHECKING:
    from stepnc_graph.loader import LoadResult
    from stepnc_graph.part21 import Part21SyntaxError
    from stepnc_graph.store import GraphStore

EXIT_OK, EXIT_NONCONFORMING, EXIT_BAD_INPUT = 0, 1, 2

out = Console(highlight=False, soft_wrap=True)
err = Console(stderr=True, highlight=False, soft_wrap=True)


def _fail_input(exc: Exception, fmt: str = "text") -> NoReturn:
    errors = exc.errors if isinstance(exc, SchemaErrors) else [exc]
    if fmt == "json":
        click.echo(json.dumps({"ok": False, "errors": [e.asdict() for e in errors]}, indent=2))  # type: ignore[attr-defined]
    else:
        err.print(f"[bold red]error:[/] {exc}", markup=True)
    sys.exit(EXIT_BAD_INPUT)


_root_option = click.option(
    "--root", type=click.Path(file_okay=False, path_type=Path), default=None,
    help="Project root holding ontology/express/ (default: this checkout, or the installed data).")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="stepnc-graph")
def main() -> None:
    """STEP-NC (ISO 14649) process data as a knowledge graph.

    The EXPRESS schemas of ISO 14649 are compiled to an OWL vocabulary;
    Part 21 programs become RDF you can query with SPARQL and check with SHACL.

    Exit codes: 0 ok, 1 non-conforming data, 2 bad input or usage.
    """


@main.group()
def ontology() -> None:
    """Build and inspect the OWL vocabulary generated from ontology/express/."""


@ontology.command("build")
@_root_option
@click.option("--check", is_flag=True, help="Write nothing; exit 1 if any generated file differs from a fresh build.")
def ontology_build(root: Path | None, check: bool) -> None:
    """Regenerate ontology/*.ttl, docs/ontology.html and the Python vocabulary.

    Output is byte-stable: building twice changes nothing.
    """
    from stepnc_graph.build import build

    root = root or data_root()
    started = time.perf_counter()
    try:
        with err.status("building the ontology from ontology/express/ ..."):
            result = build(root, check=check)
    except (ExpressSyntaxError, SchemaError) as exc:
        _fail_input(exc)
    seconds = time.perf_counter() - started
    if check:
        for rel in result.stale:
            out.print(f"stale: {rel}")
        out.print(f"{len(result.unchanged)} up to date, {len(result.stale)} stale ({seconds:.2f} s)")
        sys.exit(EXIT_NONCONFORMING if result.stale else EXIT_OK)
    for rel in result.written:
        out.print(f"wrote {rel}")
    out.print(f"{len(result.written)} written, {len(result.unchanged)} unchanged ({seconds:.2f} s)")


@ontology.command("stats")
@_root_option
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
def ontology_stats_cmd(root: Path | None, fmt: str) -> None:
    """Entities, types and attributes per schema: in the EXPRESS and in the ontology.

    The two counts must be equal (100 % coverage); exit 1 if they are not.
    """
    from stepnc_graph.stats import ontology_stats

    try:
        rows = ontology_stats(root or data_root())
    except (ExpressSyntaxError, SchemaError) as exc:
        _fail_input(exc, fmt)
    complete = all(r.complete for r in rows)
    if fmt == "json":
        click.echo(json.dumps({"complete": complete, "schemas": [r.asdict() for r in rows]}, indent=2))
    else:
        table = Table(title="ISO 14649 ontology coverage (EXPRESS / OWL)")
        for col in ("schema", "entities", "types", "attributes", "complete"):
            table.add_column(col, justify="left" if col == "schema" else "right")
        for r in rows:
            table.add_row(r.schema, f"{r.express_entities} / {r.owl_entities}", f"{r.express_types} / {r.owl_types}",
                          f"{r.express_attributes} / {r.owl_attributes}", "yes" if r.complete else "NO")
        table.add_row("total", *(f"{sum(getattr(r, 'express_' + k) for r in rows)} / "
                                 f"{sum(getattr(r, 'owl_' + k) for r in rows)}"
                                 for k in ("entities", "types", "attributes")), "yes" if complete else "NO")
        out.print(table)
    sys.exit(EXIT_OK if complete else EXIT_NONCONFORMING)


@main.group()
def schema() -> None:
    """Check EXPRESS schema files."""


@schema.command("check")
@click.argument("files", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--parse-only", is_flag=True, help="Only parse; do not resolve names across the files.")
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
def schema_check(files: tuple[Path, ...], parse_only: bool, fmt: str) -> None:
    """Parse EXPRESS FILES and resolve them together into one model.

    Reports the first syntax error of a file (with line, column and a caret),
    or every resolution error (unknown type, cycle, duplicate name). Exit 2 on
    any error.
    """
    parsed: list[ParsedSchema] = []
    timings = {}
    try:
        for f in files:
            started = time.perf_counter()
            parsed.extend(parse_file(f))
            timings[str(f)] = time.perf_counter() - started
        model = None if parse_only else build_model(parsed)
    except (ExpressSyntaxError, SchemaError) as exc:
        _fail_input(exc, fmt)
    summary = {
        "ok": True,
        "schemas": [p.name for p in parsed],
        "parse_seconds": {k: round(v, 3) for k, v in timings.items()},
        "entities": len(model.entities) if model else None,
        "types": len(model.types) if model else None,
    }
    if fmt == "json":
        click.echo(json.dumps(summary, indent=2))
        return
    for name, seconds in timings.items():
        out.print(f"parsed {name} in {seconds:.2f} s")
    if model is not None:
        out.print(f"{len(parsed)} schema(s) resolved: {len(model.entities)} entities, {len(model.types)} types")
    else:
        out.print(f"{len(parsed)} schema(s) parsed")


@schema.command("entity")
@click.argument("names", nargs=-1, required=True)
def schema_entity(names: tuple[str, ...]) -> None:
    """Show entities of the shipped schemas: supertypes and Part 21 parameters in order.

    Exit 2 if a name is not an entity.
    """
    from stepnc_graph.schema.catalog import iso14649

    _, model = iso14649()
    status = EXIT_OK
    for name in names:
        decl = model.get(name)
        if decl is None or model.kind_of(name) != "entity":
            err.print(f"[bold red]error:[/] {name} is not an entity of the shipped schemas")
            status = EXIT_BAD_INPUT
            continue
        e = model.entity(name)
        clause = model.clause(e.name)
        out.print(f"{e.name.upper()} ({e.schema}{', clause ' + clause if clause else ''})"
                  f"{' ABSTRACT' if e.abstract else ''}; supertypes: {', '.join(model.ancestors(e.name)) or '-'}")
        for slot in model.part21_attributes(e.name):
            flags = (" OPTIONAL" if slot.optional else "") + (" (derived: *)" if slot.derived else "")
            out.print(f"  {slot.index + 1:2d} {slot.name} : {slot.type}{flags}   [{slot.attribute.entity}]")
    sys.exit(status)


# -- Part 21 programs in the store ---------------------------------------------------

_store_options = [
    click.option("--store", "store_path", type=click.Path(file_okay=False, path_type=Path), default=None,
                  help="Store directory (default: $STEPNC_GRAPH_STORE, else ./.stepnc-graph)."),
    click.option("--memory", is_flag=True, help="Use a throw-away in-memory store."),
]


F = TypeVar("F", bound=Callable[..., Any])


def _with_store(f: F) -> F:
    """Add the --store / --memory options every store command shares."""
    for option in reversed(_store_options):
        f = option(f)
    return f


def _open(store_path: Path | None, memory: bool) -> GraphStore:
    from stepnc_graph.api import open_store
    from stepnc_graph.store import StoreError

    try:
        return open_store(store_path, memory)
    except StoreError as exc:
        err.print(f"[bold red]error:[/] {exc}")
        sys.exit(EXIT_BAD_INPUT)


def _progress_bar() -> Progress:

    return Progress("[progress.description]{task.description}", BarColumn(), DownloadColumn(),
                    TimeRemainingColumn(), console=err, transient=True)


@main.command("load")
@click.argument("files", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False, path_type=Path))
@_with_store
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
    with _open(store_path, memory) as store:
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


@main.command("export")
@_with_store
@click.option("--graph", default=None, help="The graph to export (see `stepnc-graph info`); default: all, "
                                            "or the only one.")
@click.option("--format", "fmt", type=click.Choice(["ttl", "nt", "nq", "trig", "jsonld", "p21"]), required=True,
              help="p21 writes the graph back as a Part 21 file.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write here instead of standard output.")
def export_cmd(store_path: Path | None, memory: bool, graph: str | None, fmt: str, output: Path | None) -> None:
    """Export one graph or the whole store as RDF or as Part 21."""
    from stepnc_graph.export import ExportError, export

    with _open(store_path, memory) as store:
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


@main.command("unload")
@click.argument("graphs", nargs=-1, required=True)
@_with_store
def unload_cmd(graphs: tuple[str, ...], store_path: Path | None, memory: bool) -> None:
    """Remove loaded files' graphs (GRAPHS are graph IRIs, see `stepnc-graph info`). Exit 1 if one was absent."""
    from stepnc_graph.api import unload

    with _open(store_path, memory) as store:
        missing = [g for g in graphs if not unload(store, g)]
    for g in graphs:
        out.print(f"{'not in the store' if g in missing else 'removed'}: {g}")
    sys.exit(EXIT_NONCONFORMING if missing else EXIT_OK)


@main.command("info")
@_with_store
@click.option("--format", "fmt", type=click.Choice(["text", "json"]), default="text", show_default=True)
def info_cmd(store_path: Path | None, memory: bool, fmt: str) -> None:
    """List the graphs in the store with their source file and counts."""
    from stepnc_graph.api import info
    from stepnc_graph.store import default_store_path

    with _open(store_path, memory) as store:
        rows = info(store)
    if fmt == "json":
        click.echo(json.dumps({"graphs": [r.asdict() for r in rows]}, indent=2))
        return
    out.print(f"{len(rows)} graph(s) in {'memory' if memory else store_path or default_store_path()}")
    for r in rows:
        # one block per graph, IRI on its own line: it is what users copy into --graph / unload
        out.print(f"{r.graph}\n  source {r.source}; {r.instances} instances ({r.raw_instances} raw), "
                  f"{r.triples} triples, {r.diagnostics} diagnostics; loaded {r.loaded}")


if __name__ == "__main__":  # pragma: no cover
    main()
