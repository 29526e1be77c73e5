"""The command line answers every user error with one line (or a JSON object) and exit 2.

Each case failed before issue 7's hardening (tracebacks with exit 1, stores created by a
typo, graphs of two same-named files replacing each other silently, ...).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

import stepnc_graph as sg
from stepnc_graph.cli import main

from conftest import ROOT
from test_load import HEADER

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
CLI = [sys.executable, "-m", "stepnc_graph.cli"]


def run(*args: str, input: bytes | None = None) -> subprocess.CompletedProcess[str]:
    """The real command in a child process (tracebacks would show on its stderr)."""
    return subprocess.run([*CLI, *args], capture_output=True, text=True, input=input.decode() if input else None,
                          timeout=120)


def assert_clean_error(res: subprocess.CompletedProcess[str], *needles: str) -> None:
    assert res.returncode == 2, (res.returncode, res.stdout, res.stderr)
    assert "Traceback" not in res.stderr + res.stdout
    for needle in needles:
        assert needle in res.stderr, res.stderr


# -- P2.5: tracebacks become messages ---------------------------------------------------------------


@pytest.mark.parametrize("args,needle", [
    (["load", "--memory", "--base-iri", "not an iri", str(EXAMPLE)], "--base-iri: 'not an iri' is not an absolute IRI"),
    (["export", "--format", "ttl", "--graph", "http://x/<y>"], "no graph http://x/<y> in the store"),
    (["unload", "relative/graph"], "no graph relative/graph in the store"),  # nor the end of one's IRI
])
def test_invalid_iris_are_refused(args: list[str], needle: str, tmp_path: Path) -> None:
    sg.open_store(tmp_path / "s").close()
    assert_clean_error(run(*args, "--store", str(tmp_path / "s")) if args[0] != "load" else run(*args), needle)


def test_output_into_a_missing_directory(tmp_path: Path) -> None:
    store = tmp_path / "s"
    assert run("load", "--store", str(store), str(EXAMPLE)).returncode == 0
    res = run("export", "--store", str(store), "--format", "p21", "-o", str(tmp_path / "nowhere" / "x.stp"))
    assert_clean_error(res, "does not exist")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes to read-only directories")
def test_a_store_directory_that_is_not_writable(tmp_path: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        assert_clean_error(run("load", "--store", str(locked / "s"), str(EXAMPLE)), "cannot")
    finally:
        locked.chmod(0o700)


def test_a_store_directory_without_write_permission_as_root_is_simulated(tmp_path: Path) -> None:
    """Root ignores permissions; a store path below a regular file is unwritable for everyone."""
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert_clean_error(run("load", "--store", str(blocker / "s"), str(EXAMPLE)), "cannot create the store")


def test_a_string_longer_than_16_mib_is_stored(tmp_path: Path) -> None:
    path = tmp_path / "long.stp"
    text = "x" * (17 << 20)
    path.write_text(HEADER + f"#1=PROPERTY_PARAMETER('{text}');\nENDSEC;END-ISO-10303-21;\n")
    for memory in (True, False):
        store = sg.open_store(None if memory else tmp_path / "s", memory=memory)
        [r] = sg.load(store, [path])
        [row] = store.query(f"SELECT (STRLEN(?v) AS ?n) WHERE {{ GRAPH <{r.graph}> {{ ?s "
                            f"<https://w3id.org/stepnc-graph/iso14649#property_parameter.parameter_name> ?v }} }}")
        assert int(row[0].value) == len(text)
        store.close()


@pytest.mark.parametrize("device", ["/dev/zero"])
def test_a_device_is_refused(device: str) -> None:
    if not Path(device).exists():
        pytest.skip(f"no {device}")
    assert_clean_error(run("load", "--memory", device), "not a regular file")
    assert_clean_error(run("load", "--memory", "--base-iri", "urn:x", "-", input=b"\0" * 100_000),
                       "not a Part 21 file")


def test_json_errors(tmp_path: Path) -> None:
    res = run("load", "--memory", "--format", "json", "--base-iri", "bad iri", str(EXAMPLE))
    assert res.returncode == 2
    [error] = json.loads(res.stdout)["errors"]
    assert error["type"] == "SourceError" and "not an absolute IRI" in error["message"]
    bad = tmp_path / "bad.stp"
    bad.write_text(HEADER + "#1=PROPERTY_PARAMETER('a',,);\nENDSEC;END-ISO-10303-21;\n")
    res = run("load", "--memory", "--format", "json", str(bad))
    doc = json.loads(res.stdout)
    assert res.returncode == 2 and doc["errors"][0]["line"] == 2 and doc["errors"][0]["p21_id"] == 1


def _big_program(tmp_path: Path, instances: int = 40_000) -> Path:
    sys.path.insert(0, str(ROOT / "bench"))
    from generate import write  # type: ignore[import-not-found]

    path = tmp_path / "big.stp"
    write(instances, path)
    return path


def test_ctrl_c_exits_130_and_leaves_the_store_as_it_was(tmp_path: Path) -> None:
    store = tmp_path / "s"
    assert run("load", "--store", str(store), str(EXAMPLE)).returncode == 0
    before = run("export", "--store", str(store), "--format", "nq").stdout
    big = _big_program(tmp_path, 80_000)  # several seconds of loading: the interrupt comes well before the end
    # SIGINT back to its default in the child: a test run started in the background of a
    # non-interactive shell inherits it ignored, and Python then (rightly) never raises KeyboardInterrupt
    child = subprocess.Popen([*CLI, "load", "--store", str(store), str(big)], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True,
                             preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(1.5)
    child.send_signal(signal.SIGINT)
    stdout, stderr = child.communicate(timeout=60)
    assert child.returncode == 130, (stdout, stderr)
    assert "Traceback" not in stderr and "interrupted" in stderr
    assert run("export", "--store", str(store), "--format", "nq").stdout == before


# -- P3.9: graphs never replace each other silently ----------------------------------------------------


def _two_same_named(tmp_path: Path) -> tuple[Path, Path]:
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    (a / "part.stp").write_text(HEADER + "#1=PROPERTY_PARAMETER('a');\nENDSEC;END-ISO-10303-21;\n")
    (b / "part.stp").write_text(HEADER + "#1=PROPERTY_PARAMETER('b');\nENDSEC;END-ISO-10303-21;\n")
    return a / "part.stp", b / "part.stp"


def test_same_file_names_in_one_command_are_refused(tmp_path: Path) -> None:
    a, b = _two_same_named(tmp_path)
    res = run("load", "--store", str(tmp_path / "s"), str(a), str(b))
    assert_clean_error(res, "would both be loaded as graph <https://w3id.org/stepnc-graph/data/part.stp>")
    assert not (tmp_path / "s").exists() or sg.info(sg.open_store(tmp_path / "s", readonly=True)) == []


def test_a_graph_holding_another_file_is_not_replaced_silently(tmp_path: Path) -> None:
    a, b = _two_same_named(tmp_path)
    store = str(tmp_path / "s")
    assert run("load", "--store", store, str(a)).returncode == 0
    assert run("load", "--store", store, str(a)).returncode == 0  # the same file again: replaced
    assert_clean_error(run("load", "--store", store, str(b)), "already holds", "--replace")
    assert run("load", "--store", store, "--replace", str(b)).returncode == 0
    [g] = sg.info(sg.open_store(store, readonly=True))
    assert g.source == str(b.resolve())


def test_load_a_directory_names_graphs_by_relative_path(tmp_path: Path) -> None:
    _two_same_named(tmp_path)
    (tmp_path / "a" / "ignored.txt").write_text("not a program")
    (tmp_path / "b" / "UPPER.STEP").write_text(EXAMPLE.read_text())
    res = run("load", "--store", str(tmp_path / "s"), "--format", "json", str(tmp_path))
    assert res.returncode == 0, res.stderr
    graphs = [f["graph"] for f in json.loads(res.stdout)["files"]]
    assert graphs == ["https://w3id.org/stepnc-graph/data/a/part.stp", "https://w3id.org/stepnc-graph/data/b/UPPER.STEP",
                      "https://w3id.org/stepnc-graph/data/b/part.stp"]


def test_load_standard_input(tmp_path: Path) -> None:
    store = str(tmp_path / "s")
    assert_clean_error(run("load", "--store", store, "-", input=EXAMPLE.read_bytes()), "--base-iri")
    res = run("load", "--store", store, "--base-iri", "https://plm.example.org/p/1", "-", input=EXAMPLE.read_bytes())
    assert res.returncode == 0, res.stderr
    [g] = sg.info(sg.open_store(store, readonly=True))
    assert (g.graph, g.source, g.instances) == ("https://plm.example.org/p/1", "<stdin>", 89)


# -- P3.13: readers never create, --memory only where it means something ------------------------------


def test_only_load_creates_a_store(tmp_path: Path) -> None:
    typo = tmp_path / "mistyped"
    assert_clean_error(run("info", "--store", str(typo)), "no store at")
    assert_clean_error(run("export", "--store", str(typo), "--format", "nq"), "no store at")
    assert_clean_error(run("unload", "--store", str(typo), "urn:x"), "no store at")
    assert_clean_error(run("compact", "--store", str(typo)), "no store at")
    mapping = tmp_path / "ids.csv"
    mapping.write_text("p21_id,identifier\n1,X\n")
    assert_clean_error(run("link", str(mapping), "--store", str(typo)), "no store at")
    assert not typo.exists()


@pytest.mark.parametrize("command", [["info"], ["export", "--format", "nq"], ["unload", "urn:x"]])
def test_memory_is_refused_where_it_means_nothing(command: list[str]) -> None:
    res = CliRunner().invoke(main, [*command, "--memory"])
    assert res.exit_code == 2 and "No such option '--memory'" in res.output


def test_unload_and_export_agree_on_a_missing_graph(tmp_path: Path) -> None:
    store = str(tmp_path / "s")
    assert run("load", "--store", store, str(EXAMPLE)).returncode == 0
    assert_clean_error(run("unload", "--store", store, "urn:nope"), "no graph urn:nope")
    assert_clean_error(run("export", "--store", store, "--format", "ttl", "--graph", "urn:nope"), "no graph urn:nope")


def test_info_shows_absolute_source_paths(tmp_path: Path) -> None:
    shutil.copy(EXAMPLE, tmp_path / "rel.stp")
    res = subprocess.run([*CLI, "load", "--store", "s", "rel.stp"], cwd=tmp_path, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
    info = subprocess.run([*CLI, "info", "--store", "s"], cwd=tmp_path, capture_output=True, text=True)
    assert f"source {tmp_path / 'rel.stp'};" in info.stdout


def test_ontology_stats_does_not_cut_names_when_piped() -> None:
    res = run("ontology", "stats")
    assert "turning_machine_tool_schema" in res.stdout and "…" not in res.stdout


def test_schema_help_mentions_entity() -> None:
    assert "entity" in CliRunner().invoke(main, ["schema", "--help"]).output


def test_lenient_hint_only_where_it_helps(tmp_path: Path) -> None:
    bad = tmp_path / "bad.stp"
    bad.write_text(HEADER + "#1=PROPERTY_PARAMETER('a',,);\nENDSEC;END-ISO-10303-21;\n")
    assert "--lenient loads what can be read" in run("load", "--memory", str(bad)).stderr
    empty = tmp_path / "empty.stp"
    empty.write_text("")
    for args in (["--lenient", str(bad.with_name("x.stp"))], [str(empty)], ["--lenient", str(empty)]):
        if args[-1].endswith("x.stp"):
            Path(args[-1]).write_text("ISO-10303-21;\nHEADER;\nFILE_NAME(;\n")  # broken header
        res = run("load", "--memory", *args)
        assert res.returncode == 2 and "--lenient" not in res.stderr, res.stderr


# -- P3.12: deterministic exports ----------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["ttl", "nt", "nq", "trig", "jsonld", "p21"])
def test_two_loads_give_the_same_export_bytes(fmt: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")  # the load time, as reproducible builds set it
    exports = []
    for _ in range(2):
        store = sg.open_store(memory=True)
        [r] = sg.load(store, [EXAMPLE])
        exports.append(sg.export(store, fmt, None if fmt in ("nq", "trig") else r.graph))
    assert exports[0] == exports[1]
    if fmt == "nt":
        labels = set(re.findall(rb"_:(\w+)", exports[0]))
        assert labels and all(re.fullmatch(rb"i\d+b\d+", label) for label in labels)
