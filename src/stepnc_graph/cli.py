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
from typing import NoReturn

import click
from rich.console import Console
from rich.table import Table

from stepnc_graph import __version__
from stepnc_graph.express import ExpressSyntaxError, parse_file
from stepnc_graph.express.parser import ParsedSchema
from stepnc_graph.resources import data_root
from stepnc_graph.schema import SchemaError, SchemaErrors, build_model

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
    for f, seconds in timings.items():
        out.print(f"parsed {f} in {seconds:.2f} s")
    if model is not None:
        out.print(f"{len(parsed)} schema(s) resolved: {len(model.entities)} entities, {len(model.types)} types")
    else:
        out.print(f"{len(parsed)} schema(s) parsed")


if __name__ == "__main__":  # pragma: no cover
    main()
