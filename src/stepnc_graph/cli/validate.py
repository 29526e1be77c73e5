"""`stepnc-graph validate`: check programs (or any RDF data) against the generated shapes, the process
rules and your own."""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import click

from stepnc_graph.cli.common import (
    format_choice,
    EXIT_NONCONFORMING,
    EXIT_OK,
    RemoteOptions,
    UsageProblem,
    err,
    escape,
    is_terminal,
    open_reader,
    pick_graph,
    reports_errors,
    with_endpoint,
    write_out,
)


@contextmanager
def phases() -> Iterator[Callable[[str], None] | None]:
    """On a terminal, a transient status line on stderr naming the phase a long validation is in,
    with the seconds since it began; elsewhere nothing (None)."""
    if not is_terminal(err.file):
        yield None
        return
    started = time.monotonic()
    with err.status("validating", spinner="dots") as status:
        def show(text: str) -> None:
            status.update(f"{escape(text)}  [dim]{time.monotonic() - started:,.0f} s[/]")
        yield show


@click.command("validate")
@click.argument("files", nargs=-1, type=click.Path(exists=True, dir_okay=False, allow_dash=True, path_type=Path))
@click.option("--store", "store_path", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Validate graphs of this store instead of FILES (its last published state: a load "
                   "running meanwhile is not waited for).")
@with_endpoint
@click.option("--graph", "graphs", multiple=True, help="A graph of the store to validate (repeatable; default: all).")
@click.option("--format", "fmt", type=format_choice(["text", "json", "turtle"]), default="text", show_default=True)
@click.option("--severity", type=click.Choice(["violation", "warning", "info"]), default="info", show_default=True,
              help="The lowest severity reported.")
@click.option("--shapes", "extra", multiple=True,
              type=click.Path(exists=True, dir_okay=False, allow_dash=True, path_type=Path),
              help="An extra SHACL shapes file (Turtle), e.g. an organisation's own rules (repeatable). Not -: "
                   "shapes are compiled once per file and kept while it is unchanged; standard input is for "
                   "FILES.")
@click.option("--no-iso-shapes", "no_iso", is_flag=True,
              help="Leave out the ISO 14649 shapes and process rules: only --shapes run (a general SHACL "
                   "validator for any RDF data). Programs of another edition are then checked by those only; the "
                   "report notes it.")
@click.option("--strict", is_flag=True, help="Stop at the first Part 21 syntax error (exit 2) instead of "
                                             "recovering and reporting it.")
@click.option("--allow-service", is_flag=True,
              help="Let SERVICE clauses in the shapes' SPARQL send requests to the servers they name (refused "
                   "otherwise). Prints a warning.")
@click.option("--edition", type=click.Choice(["2002", "fdis2001"]), default=None,
              help="Read FILES in this edition of ISO 14649 whatever they show (default: each file's own, as "
                   "load decides it); the edition's rules apply.")
@click.option("--max-results", type=click.IntRange(min=0), default=None, metavar="N",
              help="List at most N results (text and json; the counts and the summary by rule cover all).")
@reports_errors
def validate_cmd(files: tuple[Path, ...], store_path: Path | None, remote: RemoteOptions, graphs: tuple[str, ...],
                 fmt: str, severity: str, extra: tuple[Path, ...], strict: bool, no_iso: bool,
                 allow_service: bool, edition: str | None, max_results: int | None) -> None:
    """Check FILES (loaded into a throw-away store) or a store's graphs.

    FILES are Part 21 programs (.stp, .step, .p21), JSON-LD program graphs
    (.jsonld) or any RDF data (.ttl, .nt, .nq, .trig, .rdf; a file's graphs are
    validated together); - is a Part 21 program on standard input (messages
    name it <stdin>). Every result gives the node (for a program: #id,
    entity, line), the attribute or path, the value found, what was expected,
    the rule and its ISO clause. Problems the loader finds (unknown entity,
    wrong parameter count or type, unresolved reference, recovered syntax, an
    ill-typed literal) are results too.

    The text report ends with how many results each rule gave; on a terminal
    each phase (loading, checking, describing) shows while it runs.

    The Turtle and JSON reports carry SHACL's sh:conforms (false when there is
    any result). Exit codes: 0 no violation (warnings and infos do not fail),
    1 violations, 2 bad input, refused shapes or usage.
    """
    from stepnc_graph.validation import validate

    if any(str(f) == "-" for f in extra):
        raise UsageProblem("--shapes -: shapes are read from a file (compiled once per file and kept while it is "
                           "unchanged); standard input is for FILES (validate - reads a program from it)")
    in_store = store_path is not None or remote.wanted(store_path, bool(files))
    if bool(files) == in_store:
        raise UsageProblem("give FILES, or --store DIR / --endpoint URL; not both and not neither")
    if graphs and not in_store:
        raise UsageProblem("--graph needs --store or --endpoint")
    if edition and in_store:
        raise UsageProblem("--edition reads FILES; a store's graphs keep the edition they were loaded in")
    if allow_service:
        err.print("[yellow]warning:[/] --allow-service: SERVICE clauses in the shapes send requests to the servers "
                  "they name", markup=True, highlight=False)
    # refused shapes, unreadable data, a store that cannot be read: errors of the project's root,
    # reported by @reports_errors (exit 2); a --graph is one of the store's graphs or a usage error
    with phases() as progress:
        if in_store:
            with open_reader(store_path, remote) as store:
                report = validate(store, graphs=[pick_graph(store, g) for g in graphs] or None, extra_shapes=list(extra),
                                  severity=severity, iso_shapes=not no_iso, allow_service=allow_service,
                                  progress=progress)
        else:
            report = validate(list(files), extra_shapes=list(extra), severity=severity, lenient=not strict,
                              iso_shapes=not no_iso, allow_service=allow_service, edition=edition, progress=progress)
    text = (report.to_turtle() if fmt == "turtle" else report.to_json(max_results) if fmt == "json"
            else report.to_text(max_results))
    write_out(text, uchar=fmt != "text")
    sys.exit(EXIT_OK if report.passes else EXIT_NONCONFORMING)
