"""`stepnc-graph query` and `stepnc-graph queries`: on a store and on files, formats, exit codes."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from click.testing import CliRunner

from stepnc_graph.cli import main
from stepnc_graph.core.naming import DATA_BASE

from conftest import FIXTURES, ROOT

EXAMPLE = str(ROOT / "examples" / "shaft_two_setups.stp")
SLEEVE = str(FIXTURES / "query" / "sleeve_two_setups.stp")


def run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(main, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_query_on_program_files() -> None:
    code, out, err = run("query", "workingsteps-by-tool-type", EXAMPLE, "--format", "csv")
    assert code == 0, err
    rows = list(csv.DictReader(io.StringIO(out, newline="")))
    assert [(r["workingstep"], r["workingstep_ref"], r["tool"]) for r in rows] == [
        ("WS5 RELIEF GROOVE", "#34", "T02 GROOVING 3MM")]


def test_query_on_a_store_with_graph_and_params(tmp_path: Path) -> None:
    store = str(tmp_path / "store")
    assert run("load", "--store", store, EXAMPLE, SLEEVE)[0] == 0
    code, out, _ = run("query", "workingsteps-by-tool-type", "--store", store, "--param", "tool_type=knurling_tool",
                       "--format", "json")
    assert code == 0
    doc = json.loads(out)
    assert [b["workingstep"]["value"] for b in doc["results"]["bindings"]] == ["WS06 KNURL"]
    code, out, err = run("query", "tool-changes", "--store", store, "--graph", DATA_BASE + "shaft_two_setups.stp")
    assert code == 0 and "WS5 RELIEF GROOVE" in out and "WS06" not in out and "2 row(s)" in err
    code, out, _ = run("query", "-e", "SELECT (COUNT(*) AS ?n) WHERE { ?s sga:executes ?ws }", "--store", store,
                       "--format", "tsv")
    assert code == 0 and out.splitlines() == ["?n", "21"]  # TSV writes integers in their short form


def test_query_file_and_markdown(tmp_path: Path) -> None:
    rq = tmp_path / "setups.rq"
    rq.write_text("# title: setups\nSELECT ?setup WHERE { ?s a stepnc:setup ; attr:its_id ?setup } ORDER BY ?setup\n")
    code, out, _ = run("query", str(rq), EXAMPLE, "--format", "md")
    assert code == 0 and out.splitlines() == ["| setup |", "|---|", "| SETUP 1 |", "| SETUP 2 |"]


def test_errors_exit_2_with_positions(tmp_path: Path) -> None:
    code, _, err = run("query", "-e", "SELECT ?x WHERE {\n ?x ?y\n}", EXAMPLE)
    assert code == 2 and "-e:3:" in err and "syntax error" in err
    code, _, err = run("query", "workingsteps-by-tool-type", "--param", "tool_type=spoon", EXAMPLE)
    assert code == 2 and "workingsteps-by-tool-type.rq:6" in err and "no class 'spoon'" in err
    code, _, err = run("query", "workingsteps-by-tool-type", "--param", "tool_type", EXAMPLE)
    assert code == 2 and "expected NAME=VALUE" in err
    assert run("query", "no-such-query", EXAMPLE)[0] == 2
    assert run("query", "tool-changes", str(tmp_path / "missing.stp"))[0] == 2
    assert run("query", "tool-changes", "--memory", EXAMPLE)[0] == 2  # a store and files: not both
    assert run("query")[0] == 2
    bad = tmp_path / "bad.stp"
    bad.write_text(Path(EXAMPLE).read_text().replace("#292=DIRECTION('-Z',(0.,0.,-1.));", "#292=DIRECTION(,"))
    code, _, err = run("query", "tool-changes", str(bad))
    assert code == 2 and "nothing loaded" in err


def test_queries_lists_the_library() -> None:
    code, out, _ = run("queries")
    assert code == 0 and "workingsteps-by-tool-type" in out and "--param tool_type (class) = grooving_tool" in out
    code, out, _ = run("queries", "--format", "json")
    names = [q["name"] for q in json.loads(out)["queries"]]
    assert code == 0 and "tool-changes" in names and len(names) >= 15
    code, out, _ = run("queries", "setup-sheet")
    assert code == 0 and "SELECT ?program ?setup" in out
    assert run("queries", "nothing-like-that")[0] == 2
