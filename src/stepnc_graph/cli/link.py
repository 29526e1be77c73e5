"""`stepnc-graph link`: attach PLM identifiers to a program's instances, in a graph of their own.

A write: it takes the store's writer lock (another writer fails with exit 2, or
waits with ``--wait``). The work is :func:`stepnc_graph.loading.link.link`.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from stepnc_graph.cli.common import (
    format_choice,
    EXIT_NONCONFORMING,
    RemoteOptions,
    UsageProblem,
    escape,
    open_writer,
    out,
    pick_graph,
    reports_errors,
    store_option,
    wait_option,
    with_endpoint,
)


@click.command("link")
@click.argument("mapping", type=click.Path(exists=True, dir_okay=False, allow_dash=True, path_type=Path))
@click.option("--graph", default=None, help="The program graph to link (see `stepnc-graph info`); default: the "
                                            "store's only program.")
@store_option
@with_endpoint
@wait_option
@click.option("--allow-unknown", is_flag=True,
              help="Link the rows that match and report the others (exit 1), instead of linking nothing (exit 2).")
@click.option("--replace", is_flag=True, help="Replace the links of another mapping file with the same file name.")
@click.option("--format", "fmt", type=format_choice(["text", "json"]), default="text", show_default=True)
@reports_errors
def link_cmd(mapping: Path, graph: str | None, store_path: Path | None, remote: RemoteOptions, wait: bool,
             allow_unknown: bool, replace: bool, fmt: str) -> None:
    """Attach PLM identifiers (part numbers, tool catalogue numbers, document IDs) to program entities.

    MAPPING is a CSV file (header: its_id and/or p21_id, optional scope,
    identifier and/or same_as) or a JSON list of objects with those keys. Each
    row names one entity of the program -- by its its_id (scope: the entity it
    belongs to, e.g. machining_tool, executable, machining_workingstep), or by
    its #id (p21_id) -- and attaches a dcterms:identifier (identifier) and/or an
    owl:sameAs IRI (same_as). The links go into the graph
    <program graph>/links/<mapping file name>, with their provenance; the program
    graph is not changed. Linking a mapping again replaces its links. MAPPING
    is a file, not - (standard input): the link graph is named by the file's
    name, records where it came from, and a second link of the same file
    replaces the first.

    Exit codes: 0 every row linked; 1 some rows matched no single entity
    (--allow-unknown; they are listed); 2 rows matched no single entity (none
    linked, they are listed), or bad input or usage.
    """
    from stepnc_graph.loading.link import link

    if str(mapping) == "-":
        raise UsageProblem("link -: the mapping must be a file, not standard input: its link graph is named "
                           "<program>/links/<file name> and records the file it came from")
    with open_writer(store_path, wait=wait, remote=remote, create=False) as store:
        result = link(store, mapping, pick_graph(store, graph) if graph is not None else None,
                      allow_unknown=allow_unknown, replace=replace)
    if fmt == "json":
        click.echo(json.dumps(result.asdict(), indent=2))
    else:
        out.print(f"linked {result.links} entities of {escape(result.graph)} from {escape(result.mapping)}\n"
                  f"  -> {escape(result.link_graph)} ({result.triples} triples)")
        for problem in result.problems:
            out.print(f"  [yellow]not linked[/] {escape(str(problem))}")
    if result.problems:
        sys.exit(EXIT_NONCONFORMING)
