"""`stepnc-graph plan`: the workplan of a program as a summary, GraphML and a picture."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from stepnc_graph.cli.common import (
    format_choice,
    EXIT_BAD_INPUT,
    EXIT_OK,
    RemoteOptions,
    err,
    escape,
    out,
    pick_graph,
    reports_errors,
    with_endpoint,
    with_store,
    write_out,
)
from stepnc_graph.cli.query import open_programs


def _fail(message: str) -> None:
    err.print(f"[bold red]error:[/] {escape(message)}", markup=True, highlight=False)
    sys.exit(EXIT_BAD_INPUT)


@click.command("plan")
@click.argument("program", required=False, type=click.Path(dir_okay=False, path_type=Path))
@with_store
@with_endpoint
@click.option("--graph", default=None, help="The loaded program to show (see `stepnc-graph info`); needed when "
                                            "the store holds several.")
@click.option("--format", "fmt", type=format_choice(["text", "json"]), default="text", show_default=True)
@click.option("--graphml", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also write the plan graph as GraphML (for yEd, Gephi, Cytoscape).")
@click.option("--svg", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also write a picture, titled by the project: setups as lanes, workingsteps in order (operation, "
                   "feature, technology, tool) coloured by tool body type with a legend, tool changes marked, "
                   "rough/finish pairs joined.")
@click.option("--png", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="The picture as PNG (needs: pip install 'stepnc-graph[png]').")
@click.option("--page", type=click.IntRange(min=1), default=1, show_default=True,
              help="The page of the picture: a plan of more than 48 workingsteps is drawn as runs of steps with "
                   "one setup and one tool, 120 runs a page.")
@click.option("--lenient", is_flag=True, help="Load PROGRAM leniently.")
@reports_errors
def plan_cmd(program: Path | None, store_path: Path | None, memory: bool, remote: RemoteOptions, graph: str | None,
             fmt: str, graphml: Path | None, svg: Path | None, png: Path | None, page: int, lenient: bool) -> None:
    """The workplan of PROGRAM (a Part 21 file; - reads it from standard input) or of a program
    in the store.

    Prints the project's name, the execution order by setup, the tool changes,
    precedence errors (finishing before roughing on a feature), tools shared
    across setups and the critical (most used) tool. Exit 2 for bad input.
    """
    from stepnc_graph.workplan.plan import PlanError, PlanPicture, build_plan
    from stepnc_graph.workplan.plan import png as to_png

    with open_programs([program] if program is not None else [], store_path, memory, remote, lenient) as store:
        try:
            # the networkx graph only for what shows it (GraphML, the JSON summary's counts)
            picked = pick_graph(store, graph) if graph is not None else None
            plan = build_plan(store, picked, network=bool(graphml) or fmt == "json")
        except PlanError as exc:
            _fail(str(exc))
    drawn = PlanPicture(plan) if (svg or png) else None  # one picture: its page and its page count
    try:
        picture = drawn.render(page) if drawn is not None else ""
    except PlanError as exc:
        _fail(str(exc))
    try:
        if graphml:
            graphml.write_text(plan.graphml(), encoding="utf-8")
        if svg:
            svg.write_text(picture, encoding="utf-8")
        if png:
            png.write_bytes(to_png(picture))
    except ImportError as exc:
        _fail(str(exc))
    except OSError as exc:
        _fail(f"cannot write: {exc}")
    if fmt == "json":
        write_out(plan.to_json() + "\n", uchar=True)
    else:
        _print_summary(plan)
    for path in (graphml, svg, png):
        if path:
            err.print(f"wrote {escape(str(path))}")
    if drawn is not None and drawn.pages() > 1:
        err.print(f"the picture is page {page} of {drawn.pages()} (runs of steps with one setup and one tool); "
                  "--page N shows another")
    sys.exit(EXIT_OK)


def _print_summary(plan: object) -> None:
    """The summary as text: a few prints of many lines each (rich costs some 0.1 ms a print, and a
    program of 100k instances has 9,000 steps); the steps' lines, plain text, are written as they
    are (:func:`write_out`: escaped on a terminal)."""
    from stepnc_graph.workplan.plan import Plan

    assert isinstance(plan, Plan)
    changes = plan.tool_changes()
    # the project's name first (a program without one: its graph's IRI, which ends in its file name)
    named = f"[bold]{escape(plan.title)}[/] ({escape(plan.program)})" if plan.projects else f"[bold]{escape(plan.program)}[/]"
    out.print(f"{named}: {len(plan.steps)} workingsteps, {len(changes)} tool changes", markup=True, highlight=False)
    changed = {c.order for c in changes}
    for setup, steps in plan.workingsteps_per_setup().items():
        out.print(f"  [bold]{escape(setup or '(no setup)')}[/]", markup=True, highlight=False)
        lines = []
        for s in steps:
            mark = "T" if s.order in changed else " "
            tool = f"{s.tool.label} {s.tool.ref}" if s.tool else "-"
            lines.append(f"   {mark} {s.order:>4}. {s.workingstep.label} {s.workingstep.ref}  [{s.kind or '-'}]  "
                         f"tool {tool}")
        write_out("".join(line + "\n" for line in lines))  # as it is (rich took 0.1 CPU-s for 9,000 lines)
    late = [f"  [red]precedence:[/] {escape(p.feature.label)} {escape(p.feature.ref)}: finishing step {p.finish} runs "
            f"before roughing step {p.rough}" for p in plan.precedence_violations()]
    names = {s.tool.ref: s.tool.label for s in plan.steps if s.tool is not None}
    shared = [f"  shared tool {names.get(tool, '')} {tool}: {', '.join(setups)}".replace("tool  #", "tool #")
              for tool, setups in plan.shared_tools().items()]
    if late:
        out.print("\n".join(late), markup=True, highlight=False)
    if shared:
        out.print("\n".join(shared), markup=False, highlight=False)
    critical = plan.critical_tool()
    if critical:
        out.print(f"  critical tool: {critical[0].label} {critical[0].ref} ({critical[1]} workingsteps)",
                  markup=False, highlight=False)
