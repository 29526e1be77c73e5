"""`stepnc-graph schema`: check EXPRESS files and look up entities of the shipped schemas.

The EXPRESS front end and the model builder are imported inside ``schema
check``: ``schema entity`` reads the compiled model and never needs them.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import click

from stepnc_graph.cli.common import (EXIT_BAD_INPUT, EXIT_OK, UsageProblem, echo_json, err, escape, fail_input,
                                     format_choice, out)

if TYPE_CHECKING:
    from stepnc_graph.express.parser import ParsedSchema


@click.group()
def schema() -> None:
    """Check EXPRESS schema files (check) and look up entities of the shipped schemas (entity)."""


@schema.command("check")
@click.argument("files", nargs=-1, required=True,
                type=click.Path(exists=True, dir_okay=False, allow_dash=True, path_type=Path))
@click.option("--parse-only", is_flag=True, help="Only parse; do not resolve names across the files.")
@click.option("--format", "fmt", type=format_choice(["text", "json"]), default="text", show_default=True)
def schema_check(files: tuple[Path, ...], parse_only: bool, fmt: str) -> None:
    """Parse EXPRESS FILES and resolve them together into one model.

    Reports the first syntax error of a file (with line, column and a caret),
    or every resolution error (unknown type, cycle, duplicate name). - reads
    a file from standard input (messages name it <stdin>). Exit 2 on any error.
    """
    from stepnc_graph.express import ExpressSyntaxError, parse_file, parse_text
    from stepnc_graph.schema import SchemaError, build_model

    parsed: list[ParsedSchema] = []
    timings = {}
    if sum(str(f) == "-" for f in files) > 1:
        fail_input(UsageProblem("standard input (-) is given twice: it can be read once"), fmt)
    try:
        for f in files:
            started = time.perf_counter()
            if str(f) == "-":
                parsed.extend(parse_text(sys.stdin.read(), "<stdin>"))
            else:
                parsed.extend(parse_file(f))
            timings["<stdin>" if str(f) == "-" else str(f)] = time.perf_counter() - started
        model = None if parse_only else build_model(parsed)
    except (ExpressSyntaxError, SchemaError) as exc:
        fail_input(exc, fmt)
    summary = {
        "ok": True,
        "schemas": [p.name for p in parsed],
        "parse_seconds": {k: round(v, 3) for k, v in timings.items()},
        "entities": len(model.entities) if model else None,
        "types": len(model.types) if model else None,
    }
    if fmt == "json":
        echo_json(summary)
        return
    for name, seconds in timings.items():
        out.print(f"parsed {escape(name)} in {seconds:.2f} s")
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
            err.print(f"[bold red]error:[/] {escape(name)} is not an entity of the shipped schemas")
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


