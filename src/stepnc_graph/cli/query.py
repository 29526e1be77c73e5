"""`stepnc-graph query` and `stepnc-graph queries`: SPARQL over loaded programs, and the query library."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click

from stepnc_graph.core.formats import QUERY_RESULT_FORMATS
from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.cli.common import (
    EXIT_BAD_INPUT,
    EXIT_OK,
    RemoteOptions,
    echo_json,
    err,
    escape,
    format_choice,
    is_terminal,
    open_reader,
    out,
    pick_graph,
    reports_errors,
    safe_cell,
    table_width,
    with_endpoint,
    with_store,
    write_out,
)

if TYPE_CHECKING:
    from stepnc_graph.store import Store

FORMATS = QUERY_RESULT_FORMATS


def _fail(message: str) -> None:
    err.print(f"[bold red]error:[/] {escape(message)}", markup=True, highlight=False)
    sys.exit(EXIT_BAD_INPUT)


def _params(pairs: tuple[str, ...]) -> dict[str, str]:
    out_: dict[str, str] = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name.strip():
            _fail(f"--param {pair!r}: expected NAME=VALUE")
        out_[name.strip()] = value
    return out_


def load_programs(store: Store, files: list[Path], lenient: bool) -> None:
    """Load FILE.stp arguments into the (throw-away) store, ``-`` from standard input as the graph
    :data:`~stepnc_graph.loading.sources.STDIN_GRAPH`; a file that cannot be read exits 2."""
    from stepnc_graph.loading.loader import load_paths
    from stepnc_graph.loading.sources import STDIN_GRAPH
    from stepnc_graph.part21 import Part21SyntaxError

    try:
        results = load_paths(store, files, lenient=lenient, stdin_graph=STDIN_GRAPH)
    except Part21SyntaxError as exc:
        _fail(f"{exc}\nnothing loaded; --lenient loads what can be read")
    except (OSError, StepncGraphError) as exc:
        _fail(str(exc))
    for r in results:
        if r.diagnostics:
            err.print(f"[yellow]note:[/] {escape(r.path)}: {len(r.diagnostics)} diagnostics "
                      f"(`stepnc-graph load {escape(r.path)}` lists them)", markup=True, highlight=False)


def open_programs(programs: list[Path], store_path: Path | None, memory: bool, remote: RemoteOptions,
                  lenient: bool) -> Store:
    """FILE.stp arguments (``-``: standard input) in a throw-away store, or the store (read-only,
    its published state)."""
    from stepnc_graph.store import GraphStore

    for p in programs:
        if str(p) != "-" and not p.is_file():
            _fail(f"{p}: no such program file")
    if programs:
        if store_path is not None or memory or remote.endpoint or remote.query_url:
            _fail("give --store/--memory/--endpoint or program files, not both")
        store = GraphStore(None)
        load_programs(store, programs, lenient)
        return store
    if memory:
        _fail("--memory: an empty throw-away store; give program files to load into it")
    return open_reader(store_path, remote)


@click.command("query")
@click.argument("args", nargs=-1)
@click.option("-e", "--expression", "text", default=None, metavar="SPARQL",
              help="Run this SPARQL text instead of a library query or a .rq file.")
@with_store
@with_endpoint
@click.option("--graph", default=None, help="Query one loaded file's graph (see `stepnc-graph info`); "
                                            "default: every loaded program.")
@click.option("--param", "params", multiple=True, metavar="NAME=VALUE",
              help="A query parameter (repeatable); see `stepnc-graph queries NAME`.")
@click.option("--format", "fmt", type=format_choice(FORMATS), default="table", show_default=True,
              help="csv, tsv and json are the SPARQL 1.1 results formats; ttl and nt are for CONSTRUCT and "
                   "DESCRIBE results. table fits a terminal's width.")
@click.option("--csv-raw", is_flag=True,
              help="csv/tsv: the W3C form exactly. By default a text starting with = + - @, tab or CR gets a "
                   "leading ' so that a spreadsheet shows it instead of running it as a formula.")
@click.option("--lenient", is_flag=True, help="Load FILE.stp arguments leniently.")
@click.option("--allow-service", is_flag=True,
              help="Let SERVICE clauses send their requests to the servers they name (refused otherwise). "
                   "Prints a warning.")
@reports_errors
def query_cmd(args: tuple[str, ...], text: str | None, store_path: Path | None, memory: bool, remote: RemoteOptions,
              graph: str | None, params: tuple[str, ...], fmt: str, csv_raw: bool, lenient: bool,
              allow_service: bool) -> None:
    """Run NAME (a library query), FILE.rq, - (SPARQL on standard input, also -e -) or -e 'SPARQL'
    over the store or over FILE.stp programs.

    \b
      stepnc-graph query workingsteps-by-tool-type --param tool_type=grooving_tool
      stepnc-graph query tool-changes examples/shaft_two_setups.stp
      stepnc-graph query -e 'SELECT ?ws ?id WHERE { ?ws a stepnc:workingstep ; attr:its_id ?id }'

    Program files after the query are loaded into a throw-away store (no
    --store then); - among them is a Part 21 program on standard input (its
    graph: https://w3id.org/stepnc-graph/data/stdin). Every library query names the program (?program, the
    file's graph IRI). Parameters are bound as RDF terms, never pasted into
    the query text. Queries are read-only, and a SERVICE clause (a request
    to another server) is refused unless --allow-service is given.

    On a terminal, control characters in values (escape sequences, the
    bidirectional overrides) are shown escaped, \\x1b; into a pipe or a file
    the values are written exactly.

    Exit codes: 0 ok; 2 a syntax error, bad parameter, unknown query or graph
    (with file, line and column where they apply).
    """
    from stepnc_graph.querying.query import Query, QueryError, execute, parse_header, refuse_service, resolve

    if text is None and not args:
        _fail("give a query: NAME, FILE.rq or -e 'SPARQL' (`stepnc-graph queries` lists the library)")
    spec, files = (text, list(args)) if text is not None else (args[0], list(args[1:]))
    programs = [Path(f) for f in files]
    if spec == "-" and "-" in files:
        _fail("standard input is read once: give the query (-) or a program (-) on it, not both")
    try:
        if spec == "-":  # `query -` and `query -e -`: the SPARQL text on standard input
            stdin = sys.stdin.read()
            query = Query("-", stdin, "<stdin>", **parse_header(stdin, "<stdin>"))
        else:
            query = resolve(spec)
        refuse_service(query, allow_service)
    except QueryError as exc:
        _fail(str(exc))
    if allow_service:
        err.print("[yellow]warning:[/] --allow-service: SERVICE clauses send requests to the servers they name",
                  markup=True, highlight=False)
    with open_programs(programs, store_path, memory, remote, lenient) as store:
        try:
            picked = pick_graph(store, graph) if graph is not None else None
            result = execute(store, query, _params(params), picked, allow_service=allow_service)
        except QueryError as exc:
            _fail(str(exc))
    for warning in result.warnings:
        err.print(f"[yellow]warning:[/] {escape(warning)}", markup=True, highlight=False)
    cell = safe_cell if is_terminal(sys.stdout) else None
    try:
        data = result.serialize(fmt, csv_raw=csv_raw, cell=cell, width=table_width())
    except QueryError as exc:
        _fail(str(exc))
    write_out(data, uchar=fmt == "json" or result.kind == "graph")
    if fmt in ("table", "md") and result.kind == "select":
        click.secho(f"{len(result)} row(s)", err=True, dim=True)  # not rich: its import is a third of the run
    sys.exit(EXIT_OK)


@click.command("queries")
@click.argument("name", required=False)
@click.option("--format", "fmt", type=format_choice(["text", "json"]), default="text", show_default=True)
def queries_cmd(name: str | None, fmt: str) -> None:
    """List the query library (names, titles, parameters), or show query NAME in full."""
    from stepnc_graph.querying.query import QueryError, describe_library, resolve

    if name is not None:
        try:
            q = resolve(name)
        except QueryError as exc:
            _fail(str(exc))
        if q.source == "-e":
            _fail(f"{name!r} is not a library query name")
        if fmt == "json":
            echo_json({"name": q.name, "title": q.title, "description": q.description,
                       "params": [p.describe() for p in q.params], "examples": list(q.examples), "sparql": q.text})
            return
        out.print(f"[bold]{escape(q.name)}[/]: {escape(q.title)}\n{escape(q.description)}", markup=True,
                  highlight=False)
        for p in q.params:
            out.print(f"  --param {p.describe()}", markup=False, highlight=False)
        for e in q.examples:
            out.print(f"  e.g. {e}", markup=False, highlight=False)
        out.print(f"[dim]{escape(q.source)}[/]", markup=True, highlight=False)
        write_out(q.text + "\n")
        return
    rows = describe_library()
    if fmt == "json":
        echo_json({"queries": rows})
        return
    width = max(len(r["name"]) for r in rows)
    for r in rows:
        out.print(f"[bold]{escape(r['name'].ljust(width))}[/]  {escape(r['title'])}", markup=True, highlight=False)
        for p in r["params"]:
            default = f" = {p['default']}" if p["default"] is not None else " (required)"
            out.print(f"{' ' * width}    --param {p['name']} ({p['type']}){default}", markup=False,
                      highlight=False)
    out.print(f"[dim]{len(rows)} queries; `stepnc-graph queries NAME` shows one, "
              f"`stepnc-graph query NAME` runs it[/]", markup=True)
