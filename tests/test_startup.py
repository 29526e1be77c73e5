"""Commands import only what they use: no rdflib, networkx, pySHACL or EXPRESS parser for a small program.

The times are measured by ``bench/startup_bench.py``; these tests pin the
imports that made them, in a fresh interpreter each.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
#: Libraries no start-up path below needs (each costs 0.02-0.1 s to import).
HEAVY = ("rdflib", "networkx", "pyshacl", "express_schema", "rich.progress", "rich.table",
         "stepnc_graph.schema.builder", "stepnc_graph.express")

_SCRIPT = """
import json, sys, warnings
warnings.filterwarnings("error", ".*compiled-model")  # a stale compiled model would warn: fail instead
from stepnc_graph.cli import main
try:
    main({args!r})
except SystemExit as exc:
    code = exc.code
print(json.dumps({{"code": code, "modules": sorted(sys.modules)}}), file=sys.stderr)
"""


def imported_by(args: list[str]) -> tuple[int, set[str]]:
    """The exit code of the command line ``args`` and the modules it imported, in a fresh interpreter."""
    done = subprocess.run([sys.executable, "-c", _SCRIPT.format(args=args)], capture_output=True, text=True,
                          cwd=ROOT)
    report = json.loads(done.stderr.strip().splitlines()[-1])
    return report["code"], set(report["modules"])


def heavy(modules: set[str]) -> list[str]:
    return [h for h in HEAVY if h in modules]


def test_help_imports_no_command_dependencies() -> None:
    code, modules = imported_by(["--help"])
    assert code == 0
    assert heavy(modules) == []
    assert "pyoxigraph" not in modules and "stepnc_graph.store" not in modules


def test_load_reads_the_compiled_model_and_imports_no_rdf_library() -> None:
    code, modules = imported_by(["load", "--memory", str(EXAMPLE)])
    assert code == 0
    assert heavy(modules) == []
    assert "stepnc_graph.schema.cache" in modules  # the model came from the compiled file


@pytest.mark.parametrize("command", [["info"], ["export", "--format", "ttl"], ["export", "--format", "p21"]])
def test_store_commands_import_no_rdf_library(tmp_path: Path, command: list[str]) -> None:
    store = str(tmp_path / "store")
    assert imported_by(["load", "--store", store, str(EXAMPLE)])[0] == 0
    code, modules = imported_by([*command, "--store", store])
    assert code == 0
    assert heavy(modules) == []


def test_schema_entity_reads_the_compiled_model() -> None:
    code, modules = imported_by(["schema", "entity", "turning_workingstep"])
    assert code == 0
    assert "express_schema" not in modules and "stepnc_graph.schema.builder" not in modules


def test_jsonld_export_imports_no_rdf_library(tmp_path: Path) -> None:
    # the JSON-LD export is written from the store's quads with the shipped context (stepnc_graph.exporting.jsonld)
    store = str(tmp_path / "store")
    assert imported_by(["load", "--store", store, str(EXAMPLE)])[0] == 0
    code, modules = imported_by(["export", "--format", "jsonld", "--store", store])
    assert code == 0 and "stepnc_graph.exporting.jsonld" in modules
    assert heavy(modules) == []


def test_stale_compiled_model_is_reported_by_the_cli(tmp_path: Path) -> None:
    data = tmp_path / "data"
    (data / "ontology").mkdir(parents=True)
    (data / "ontology" / "express").symlink_to(ROOT / "ontology" / "express")
    (data / "ontology" / "compiled-model.json").write_text('{"format": 1}\n', encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "stepnc_graph.cli", "load", "--memory", str(EXAMPLE)],
                          capture_output=True, text=True, env={"STEPNC_GRAPH_DATA": str(data), "PATH": ""})
    assert done.returncode == 0, done.stderr
    assert "warning:" in done.stderr and "compiled-model.json is not used" in done.stderr
    assert "89 instances" in done.stdout
