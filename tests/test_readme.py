"""The README's tour runs as printed, with the exit codes its comments give."""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from conftest import ROOT

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
