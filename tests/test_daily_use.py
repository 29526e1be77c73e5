"""Daily use (issue 31): what a new user trips over -- false warnings, misleading messages, output
people read. Each test here failed on the code before its fix."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

import stepnc_graph as sg
from stepnc_graph.cli import main
from stepnc_graph.core.naming import DATA_BASE
from stepnc_graph.querying.query import dataset
from stepnc_graph.store import GraphStore
from stepnc_graph.workplan.plan import build_plan

from conftest import ROOT

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
MAPPING = ROOT / "examples" / "shaft_plm_links.csv"
SHAFT = DATA_BASE + "shaft_two_setups.stp"


def linked() -> GraphStore:
    store = sg.open_store(memory=True)
    sg.load(store, [EXAMPLE])
    sg.link(store, MAPPING, SHAFT)
    return store


# -- 1: link graphs are not programs ---------------------------------------------------------------


def test_a_link_graph_is_not_counted_as_a_program() -> None:
    store = linked()
    assert sg.query(store, "tool-changes").warnings == []
    assert sg.query(store, "SELECT * WHERE { ?s ?p ?o } LIMIT 1").warnings == []
    assert build_plan(store).program == SHAFT  # the only program, beside its link graph
    assert [g.value for g in dataset(store, None)["named_graphs"]] == [SHAFT]
    rows = sg.query(store, "SELECT DISTINCT ?g WHERE { GRAPH ?g { ?s ?p ?o } }").column("g")
    assert rows == [SHAFT]


def test_cli_query_and_plan_after_link_in_an_on_disk_store(tmp_path: Path) -> None:
    store = ["--store", str(tmp_path / "store")]
    runner = CliRunner()
    assert runner.invoke(main, ["load", *store, str(EXAMPLE)]).exit_code == 0
    assert runner.invoke(main, ["link", *store, "--graph", SHAFT, str(MAPPING)]).exit_code == 0
    done = runner.invoke(main, ["query", *store, "tool-changes"])
    assert done.exit_code == 0 and "warning" not in done.stderr, done.stderr
    done = runner.invoke(main, ["plan", *store])
    assert done.exit_code == 0, done.output
