"""Concurrent processes on one on-disk store: one writer, readers never blocked, kill -9 safe.

Real processes, as users run them: a `load` of a large program in the background, `info`
readers polling it, a second writer, and `kill -9` of the writer at several moments. Before
issue 7, an `info` started during a load ran the crash recovery and destroyed the store.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import stepnc_graph as sg

from conftest import ROOT

pytestmark = pytest.mark.usefixtures("process_time_bound")

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
CLI = [sys.executable, "-m", "stepnc_graph.cli"]
BIG_GRAPH = "https://w3id.org/stepnc-graph/data/big.stp"


@pytest.fixture(scope="module")
def big(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A generated program whose load takes a few seconds here."""
    sys.path.insert(0, str(ROOT / "bench"))
    from generate import write  # type: ignore[import-not-found]

    path = tmp_path_factory.mktemp("big") / "big.stp"
    write(30_000, path)
    return path


@pytest.fixture(scope="module")
def big_triples(big: Path) -> int:
    """Triples of the big program's graph once completely loaded."""
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [big])
    return r.triples


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=300)


def start_load(store: Path, path: Path) -> subprocess.Popen[str]:
    return subprocess.Popen([*CLI, "load", "--store", str(store), str(path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def graphs(store: Path) -> dict[str, int]:
    """What a reader sees: graph -> triples (raises if the store cannot be read)."""
    with sg.open_store(store, readonly=True) as s:
        return {g.graph: g.triples for g in sg.info(s)}


class Readers:
    """``info`` processes in a loop while something else happens; every answer is kept."""

    def __init__(self, store: Path) -> None:
        self.store = store
        self.answers: list[subprocess.CompletedProcess[str]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            self.answers.append(cli("info", "--store", str(self.store), "--format", "json"))

    def __enter__(self) -> "Readers":
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=60)

    def seen(self) -> list[dict[str, int]]:
        out = []
        for a in self.answers:
            assert a.returncode == 0 and "Traceback" not in a.stderr, a.stderr
            out.append({g["graph"]: g["triples"] for g in json.loads(a.stdout)["graphs"]})
        return out


def prepared_store(tmp_path: Path) -> tuple[Path, dict[str, int]]:
    store = tmp_path / "store"
    assert cli("load", "--store", str(store), str(EXAMPLE)).returncode == 0
    return store, graphs(store)


def test_readers_see_the_state_before_a_load_until_it_is_published(tmp_path: Path, big: Path,
                                                                    big_triples: int) -> None:
    store, before = prepared_store(tmp_path)
    with Readers(store) as readers:
        time.sleep(0.3)
        writer = start_load(store, big)
        assert writer.wait(timeout=300) == 0, writer.stderr.read() if writer.stderr else ""
        time.sleep(0.5)
    after = graphs(store)
    assert after == {**before, BIG_GRAPH: big_triples}
    seen = readers.seen()
    assert len(seen) >= 3 and seen[0] == before and seen[-1] == after
    assert all(state in (before, after) for state in seen)  # never half a load


def test_a_second_writer_fails_cleanly_or_waits(tmp_path: Path, big: Path) -> None:
    store, _ = prepared_store(tmp_path)
    writer = start_load(store, big)
    time.sleep(1.0)
    second = cli("load", "--store", str(store), str(EXAMPLE))
    assert second.returncode == 2 and "Traceback" not in second.stderr
    assert f"is being written by pid {writer.pid}" in second.stderr and "--wait" in second.stderr
    unload = cli("unload", "--store", str(store), BIG_GRAPH)
    assert unload.returncode == 2 and "being written" in unload.stderr
    waiting = cli("unload", "--store", str(store), "--wait", "https://w3id.org/stepnc-graph/data/shaft_two_setups.stp")
    assert writer.wait(timeout=300) == 0
    assert waiting.returncode == 0 and "waiting for the store's writer" in waiting.stderr, waiting.stderr
    assert set(graphs(store)) == {BIG_GRAPH}


@pytest.mark.parametrize("delay", [0.3, 0.8, 1.5, 2.5])
def test_kill_9_of_a_loading_writer_while_readers_run(tmp_path: Path, big: Path, big_triples: int,
                                                        delay: float) -> None:
    store, before = prepared_store(tmp_path)
    after = {**before, BIG_GRAPH: big_triples}
    with Readers(store) as readers:
        writer = start_load(store, big)
        time.sleep(delay)
        writer.send_signal(signal.SIGKILL)
        writer.wait(timeout=60)
        time.sleep(0.3)
    assert all(state in (before, after) for state in readers.seen())
    state = graphs(store)  # a reader opens it
    assert state in (before, after)
    with sg.open_store(store, readonly=False) as s:  # the next writer recovers what the killed one left
        assert {g.graph: g.triples for g in sg.info(s)} == state
    again = cli("load", "--store", str(store), str(EXAMPLE))
    assert again.returncode == 0, again.stderr
    assert graphs(store) == state


@pytest.mark.parametrize("delay", [0.2, 0.6])
def test_kill_9_during_an_unload(tmp_path: Path, big: Path, delay: float) -> None:
    store, _ = prepared_store(tmp_path)
    assert cli("load", "--store", str(store), str(big)).returncode == 0
    loaded = graphs(store)
    child = subprocess.Popen([*CLI, "unload", "--store", str(store), BIG_GRAPH], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=60)
    state = graphs(store)
    assert state == loaded or set(state) == set(loaded) - {BIG_GRAPH}
    assert cli("unload", "--store", str(store), BIG_GRAPH).returncode in (0, 2)
    assert set(graphs(store)) == set(loaded) - {BIG_GRAPH}
