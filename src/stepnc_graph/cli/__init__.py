"""The ``stepnc-graph`` command line. The only package that prints.

One module per command group, each a thin layer over the Python API:
:mod:`.ontology`, :mod:`.schema`, :mod:`.store` (load, export, unload, info, compact),
:mod:`.link` (PLM identifiers), :mod:`.query` (query, queries), :mod:`.plan`, :mod:`.serve`.
Shared pieces (consoles, exit codes, store options) are in :mod:`.common`.

Exit codes, for scripts: 0 ok; 1 the data does not conform (diagnostics, a
stale generated file, incomplete coverage); 2 bad input or usage (syntax or
schema errors, unknown options).

Start-up time is most of a command's time on a small program, so command
modules import only click and :mod:`.common` at module level; everything else
(the store, rdflib, the EXPRESS front end, rich's tables and progress bars) is
imported inside the command that uses it. ``bench/startup_bench.py`` measures it.
"""

from __future__ import annotations

import click

from stepnc_graph.core.version import __version__
from stepnc_graph.cli import link, ontology, plan, query, schema, serve, store, validate
from stepnc_graph.cli.common import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    EXIT_NONCONFORMING,
    EXIT_OK,
    Group,
    show_warnings,
)

__all__ = ["EXIT_BAD_INPUT", "EXIT_INTERRUPTED", "EXIT_NONCONFORMING", "EXIT_OK", "main"]


@click.group(cls=Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="stepnc-graph")
def main() -> None:
    """STEP-NC (ISO 14649) process data as a knowledge graph.

    The EXPRESS schemas of ISO 14649 are compiled to an OWL vocabulary;
    Part 21 programs become RDF you can query with SPARQL and check with SHACL.

    Exit codes: 0 ok, 1 non-conforming data, 2 bad input or usage,
    130 interrupted (Ctrl-C).
    """
    show_warnings()


main.add_command(ontology.ontology)
main.add_command(schema.schema)
main.add_command(validate.validate_cmd)
main.add_command(serve.serve_cmd)
for command in (store.load_cmd, store.export_cmd, store.unload_cmd, store.info_cmd, store.compact_cmd,
                link.link_cmd):
    main.add_command(command)
main.add_command(query.query_cmd)
main.add_command(query.queries_cmd)
main.add_command(plan.plan_cmd)
