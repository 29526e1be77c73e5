"""Generated files: committed = fresh build, byte-stable, complete; the CLI's exit codes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from stepnc_graph.artefacts import build as artefacts
from stepnc_graph.artefacts.build import build
from stepnc_graph.cli import main
from stepnc_graph.artefacts.stats import ontology_stats

from conftest import FIXTURES, ROOT

pytestmark = pytest.mark.usefixtures("generate_once")


def test_committed_generated_files_equal_a_fresh_build() -> None:
    result = build(ROOT, check=True)
    assert result.stale == (), f"run `stepnc-graph ontology build`: stale {result.stale}"
    assert "ontology/turning_schema.ttl" in result.unchanged


def _digest_in_subprocess(seed: str) -> str:
    code = ("import hashlib; from stepnc_graph.artefacts.build import generate; g = generate(); "
            "print(hashlib.sha256(''.join(k + g[k] for k in sorted(g)).encode()).hexdigest())")
    env = {**os.environ, "PYTHONHASHSEED": seed}
    return subprocess.run([sys.executable, "-c", code], env=env, check=True, capture_output=True,
                          text=True).stdout.strip()


def test_build_is_byte_stable_across_processes() -> None:
    assert _digest_in_subprocess("1") == _digest_in_subprocess("4242")


def test_every_declaration_and_attribute_is_covered() -> None:
    rows = {r.schema: r for r in ontology_stats(ROOT)}
    assert all(r.complete for r in rows.values())
    turning = rows["turning_schema"]
    assert (turning.express_entities, turning.express_types) == (44, 3)
    assert sum(r.owl_entities for r in rows.values()) == sum(r.express_entities for r in rows.values()) > 400


def test_build_writes_into_a_fresh_root(tmp_path: Path) -> None:
    (tmp_path / "ontology").mkdir()
    (tmp_path / "ontology" / "express").symlink_to(ROOT / "ontology" / "express")
    first = build(tmp_path)
    assert "ontology/machining_schema.ttl" in first.written
    assert not any(w.startswith("src/") for w in first.written)  # no src/ there: skipped
    assert build(tmp_path, check=True).stale == ()
    (tmp_path / "ontology" / "p21.ttl").write_text("# edited\n")
    assert build(tmp_path, check=True).stale == ("ontology/p21.ttl",)


def test_generate_covers_every_schema() -> None:
    files = artefacts.generate(ROOT / "ontology" / "express")
    assert {f"ontology/{s}.ttl" for s in ("machining_schema", "milling_schema", "milling_tool_schema",
                                         "turning_schema", "turning_machine_tool_schema")} <= set(files)


# -- CLI ----------------------------------------------------------------------


def test_cli_stats_json_exit_0() -> None:
    res = CliRunner().invoke(main, ["ontology", "stats", "--format", "json", "--root", str(ROOT)])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    assert data["complete"] is True and len(data["schemas"]) == 18


def test_cli_build_check_exit_1_when_stale(tmp_path: Path) -> None:
    (tmp_path / "ontology").mkdir()
    (tmp_path / "ontology" / "express").symlink_to(ROOT / "ontology" / "express")
    res = CliRunner().invoke(main, ["ontology", "build", "--check", "--root", str(tmp_path)])
    assert res.exit_code == 1 and "stale: ontology/turning_schema.ttl" in res.output


def test_cli_schema_check_syntax_error_exit_2() -> None:
    bad = FIXTURES / "express" / "fail_missing_semicolon.exp"
    res = CliRunner().invoke(main, ["schema", "check", str(bad), "--format", "json"])
    assert res.exit_code == 2
    err = json.loads(res.output)["errors"][0]
    assert (err["line"], err["column"], err["type"]) == (6, 1, "ExpressSyntaxError")


def test_cli_schema_check_resolution_errors_exit_2() -> None:
    res = CliRunner().invoke(main, ["schema", "check", str(FIXTURES / "schema" / "fail_not_interfaced.exp"),
                                    "--format", "json"])
    assert res.exit_code == 2
    assert [e["line"] for e in json.loads(res.output)["errors"]] == [6, 8]


def test_cli_usage_error_exit_2_and_help() -> None:
    assert CliRunner().invoke(main, ["ontology", "nope"]).exit_code == 2
    res = CliRunner().invoke(main, ["--help"])
    assert res.exit_code == 0 and "Exit codes" in res.output


def test_console_script_runs() -> None:
    res = subprocess.run([sys.executable, "-m", "stepnc_graph.cli", "--version"], capture_output=True, text=True)
    assert res.returncode == 0 and "stepnc-graph" in res.stdout
