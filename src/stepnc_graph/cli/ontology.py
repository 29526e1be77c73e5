"""`stepnc-graph ontology`: build and inspect the generated vocabulary.

The EXPRESS front end, the schema errors and rich's tables are imported inside
the commands: every command line, ``--help`` included, imports this module.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import click

from stepnc_graph.cli.common import (
    format_choice,
    EXIT_NONCONFORMING,
    EXIT_OK,
    echo_json,
    err,
    escape,
    fail_input,
    out,
    reports_errors,
    root_option,
    UsageProblem,
)
from stepnc_graph.core.resources import data_root


@click.group()
def ontology() -> None:
    """Build and inspect the OWL vocabulary generated from ontology/express/."""


@ontology.command("build")
@root_option
@click.option("--check", is_flag=True, help="Write nothing; exit 1 if any generated file differs from a fresh build.")
def ontology_build(root: Path | None, check: bool) -> None:
    """Regenerate ontology/*.ttl, docs/ontology.html and the Python vocabulary.

    Output is byte-stable: building twice changes nothing.
    """
    from stepnc_graph.artefacts.build import build
    from stepnc_graph.express import ExpressSyntaxError
    from stepnc_graph.schema import SchemaError

    root = root or data_root()
    started = time.perf_counter()
    try:
        with err.status("building the ontology from ontology/express/ ..."):
            result = build(root, check=check)
    except (ExpressSyntaxError, SchemaError) as exc:
        fail_input(exc)
    seconds = time.perf_counter() - started
    if check:
        for rel in result.stale:
            out.print(f"stale: {escape(str(rel))}")
        out.print(f"{len(result.unchanged)} up to date, {len(result.stale)} stale ({seconds:.2f} s)")
        sys.exit(EXIT_NONCONFORMING if result.stale else EXIT_OK)
    for rel in result.written:
        out.print(f"wrote {escape(str(rel))}")
    out.print(f"{len(result.written)} written, {len(result.unchanged)} unchanged ({seconds:.2f} s)")


@ontology.command("reference")
@reports_errors
def ontology_reference_cmd() -> None:
    """Print where the HTML reference of the vocabulary is (installed with the package): every class
    with its attributes in Part 21 order, the generic property beside each, "used by" (through
    supertypes and SELECTs too) and an A-Z index. Open it in a browser."""
    from stepnc_graph.core.resources import reference_html

    path = reference_html()
    if not path.is_file():
        raise UsageProblem(f"no HTML reference at {path}: reinstall stepnc-graph")
    click.echo(str(path))


@ontology.command("stats")
@root_option
@click.option("--format", "fmt", type=format_choice(["text", "json"]), default="text", show_default=True)
def ontology_stats_cmd(root: Path | None, fmt: str) -> None:
    """Entities, types and attributes per schema: in the EXPRESS and in the ontology.

    The two counts must be equal (100 % coverage); exit 1 if they are not. Then the WHERE rules
    translated to SHACL per schema, the others with their reasons, the schema defects, and per
    other edition the rules that differ from 2002: which shape of shapes/edition_<edition>.ttl
    checks each on that edition's instances, or why none does.
    """
    from rich.table import Table

    from stepnc_graph.express import ExpressSyntaxError
    from stepnc_graph.schema import SchemaError
    from stepnc_graph.artefacts.stats import edition_rule_stats, ontology_stats, rule_stats

    try:
        rows = ontology_stats(root or data_root())
        rules = rule_stats(root or data_root())
        edition_rules = edition_rule_stats(root or data_root())
    except (ExpressSyntaxError, SchemaError) as exc:
        fail_input(exc, fmt)
    complete = all(r.complete for r in rows)
    if fmt == "json":
        echo_json({"complete": complete, "schemas": [r.asdict() for r in rows],
                   "where_rules": [r.asdict() for r in rules],
                   "edition_rules": [r.asdict() for r in edition_rules]})
    else:
        table = Table(title="ISO 14649 ontology coverage (EXPRESS / OWL)")
        for col in ("schema", "entities", "types", "attributes", "complete"):
            table.add_column(col, justify="left" if col == "schema" else "right", no_wrap=True)
        for r in rows:
            table.add_row(r.schema, f"{r.express_entities} / {r.owl_entities}", f"{r.express_types} / {r.owl_types}",
                          f"{r.express_attributes} / {r.owl_attributes}", "yes" if r.complete else "NO")
        table.add_row("total", *(f"{sum(getattr(r, 'express_' + k) for r in rows)} / "
                                 f"{sum(getattr(r, 'owl_' + k) for r in rows)}"
                                 for k in ("entities", "types", "attributes")), "yes" if complete else "NO")
        _print_table(table)
        rule_table = Table(title="WHERE rules translated to SHACL (the others are listed below)")
        for col in ("schema", "translated / total"):
            rule_table.add_column(col, justify="left" if col == "schema" else "right", no_wrap=True)
        for rs in rules:
            rule_table.add_row(rs.schema, f"{rs.translated} / {rs.total}")
        rule_table.add_row("total", f"{sum(rs.translated for rs in rules)} / {sum(rs.total for rs in rules)}")
        _print_table(rule_table)
        for rs in rules:
            for rule, why in rs.untranslated:
                out.print(f"  not translated: {escape(rs.schema)} {escape(rule)}: {escape(why)}")
        for rs in rules:
            for rule, why in rs.defects:
                out.print(f"  schema defect: {escape(rs.schema)} {escape(rule)}: {escape(why)}")
        _print_edition_rules(edition_rules)
    sys.exit(EXIT_OK if complete else EXIT_NONCONFORMING)


def _print_edition_rules(rules: list[Any]) -> None:
    """Per edition, its WHERE rules that differ from 2002 and what checks each on its instances."""
    for edition in dict.fromkeys(r.edition for r in rules):
        mine = [r for r in rules if r.edition == edition]
        out.print(f"WHERE rules of edition {escape(edition)} that differ from 2002: {len(mine)}, "
                  f"{sum(r.shape is not None for r in mine)} translated (shapes/edition_{escape(edition)}.ttl)")
        for r in mine:
            withheld = "; the 2002 rule is not applied to its instances" if r.shipped_withheld else ""
            what = (f"checked by {r.shape}{f' ({r.reason})' if r.reason else ''}" if r.shape else
                    f"not translated: {r.reason}")
            out.print(f"  {escape(r.rule)} ({escape(r.kind)}): {escape(what)}{escape(withheld)}")


def _print_table(table: Any) -> None:
    """A table on the terminal, or wide enough never to cut a name when piped (rich would use 80 columns)."""
    if out.is_terminal:
        out.print(table)
    else:
        from rich.console import Console

        Console(file=sys.stdout, width=200, highlight=False).print(table)


