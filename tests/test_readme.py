"""The README's tour runs as printed, with the exit codes its comments give."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT
from oxigraph_server import ServerUnavailable, free_port, oxigraph_server_binary, wait_until_answers

CLI = [sys.executable, "-m", "stepnc_graph.cli"]


def tour() -> list[tuple[list[str], int]]:
    text = (ROOT / "README.md").read_text()
    block = text.split("## A short tour", 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    commands = []
    for line in block.strip().splitlines():
        command, _, comment = line.partition("#")
        m = re.search(r"exit (\d)", comment)
        commands.append((shlex.split(command), int(m.group(1)) if m else 0))
    return commands


def test_every_tour_line_runs_as_printed(tmp_path: Path) -> None:
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    env = {**os.environ, "STEPNC_GRAPH_STORE": str(tmp_path / "store")}
    lines = tour()
    assert len(lines) >= 10
    for argv, expected in lines:
        assert argv[0] == "stepnc-graph"
        done = subprocess.run([*CLI, *argv[1:]], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
        assert done.returncode == expected, (argv, done.returncode, done.stdout[-800:], done.stderr[-800:])
        assert "Traceback" not in done.stderr


def test_linked_data_lines_run_as_printed(tmp_path: Path) -> None:
    """The serve / --endpoint example: each line as printed (free ports instead of 7878 and 7879)."""
    try:
        oxigraph = oxigraph_server_binary()
    except ServerUnavailable as exc:
        pytest.skip(str(exc))
    text = (ROOT / "README.md").read_text()
    block = text.split("## Linked data: serving", 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    env = {**os.environ, "STEPNC_GRAPH_STORE": str(tmp_path / "store")}
    ports = {"7878": str(free_port()), "7879": str(free_port())}
    outputs: list[str] = []
    background: list[subprocess.Popen[bytes]] = []
    try:
        for line in block.strip().splitlines():
            command = line.partition(" #")[0]
            for printed, free in ports.items():
                command = command.replace(printed, free)
            argv = shlex.split(command)
            program = {"stepnc-graph": CLI, "oxigraph": [oxigraph], "curl": [shutil.which("curl") or "curl"]}
            if argv[0] == "curl" and shutil.which("curl") is None:
                continue  # the endpoint itself is exercised by the lines after it and by test_serve.py
            full = [*program[argv[0]], *argv[1:]]
            if argv[-1] == "&":
                process = subprocess.Popen(full[:-1], cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                                           stderr=subprocess.DEVNULL)
                background.append(process)
                port = next(p for p in ports.values() if p in command)
                wait_until_answers(f"http://127.0.0.1:{port}", process)
                continue
            done = subprocess.run(full, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
            assert done.returncode == 0, (argv, done.returncode, done.stdout[-800:], done.stderr[-800:])
            outputs.append(done.stdout)
    finally:
        for process in background:
            process.terminate()
            process.wait(timeout=30)
    joined = "\n".join(outputs)
    assert "T02 GROOVING 3MM" in joined and '"@context"' in joined
    if shutil.which("curl"):
        assert "https://w3id.org/stepnc-graph/data/shaft_two_setups.stp" in outputs[1]
