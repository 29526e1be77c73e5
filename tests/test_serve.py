"""`stepnc-graph serve`, tested with real HTTP requests against the running command."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import requests

import stepnc_graph as sg

from oxigraph_server import free_port
from conftest import ROOT

pytestmark = pytest.mark.usefixtures("process_time_bound")

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
DAMAGED = ROOT / "examples" / "shaft_damaged.stp"
CLI = [sys.executable, "-m", "stepnc_graph.cli"]
COUNT = "SELECT (COUNT(*) AS ?n) WHERE { GRAPH ?g { ?s ?p ?o } }"
JSON = {"Accept": "application/sparql-results+json"}


class Serving:
    """A `stepnc-graph serve` child process on a free loopback port, stopped by its pid."""

    def __init__(self, store: Path, *options: str) -> None:
        try:
            from stepnc_graph.serve import oxigraph_binary

            oxigraph_binary()
        except Exception as e:  # noqa: BLE001 -- the reason is the skip message
            pytest.skip(f"serve cannot run here: {e}")
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.process = subprocess.Popen([*CLI, "serve", "--store", str(store), "--port", str(self.port), *options],
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for _ in range(300):
            try:
                requests.get(f"{self.url}/query", params={"query": "ASK {}"}, timeout=1)
                return
            except requests.ConnectionError:
                if self.process.poll() is not None:
                    pytest.fail(f"serve stopped: {self.process.stderr.read() if self.process.stderr else ''}")
                time.sleep(0.1)
        self.stop()
        pytest.skip("serve did not start listening within 30 s")

    def query(self, sparql: str, **params: str) -> requests.Response:
        return requests.post(f"{self.url}/query", data={"query": sparql, **params}, headers=JSON, timeout=60)

    def count(self) -> int:
        return int(self.query(COUNT).json()["results"]["bindings"][0]["n"]["value"])

    def stop(self, sig: int = signal.SIGTERM) -> tuple[int, str]:
        if self.process.poll() is None:
            os.kill(self.process.pid, sig)
        _, stderr = self.process.communicate(timeout=60)
        return self.process.returncode, stderr


@pytest.fixture
def store(tmp_path: Path) -> Path:
    path = tmp_path / "store"
    with sg.open_store(path) as s:
        sg.load(s, [EXAMPLE])
    return path


@pytest.fixture
def serving(store: Path) -> Iterator[Serving]:
    server = Serving(store)
    yield server
    server.stop()


def test_queries_are_answered_and_writes_refused(serving: Serving, store: Path) -> None:
    before = serving.count()
    assert before > 700
    for request in (lambda: requests.post(f"{serving.url}/update", data="DROP ALL",
                                          headers={"Content-Type": "application/sparql-update"}),
                    lambda: requests.put(f"{serving.url}/store", params={"graph": "urn:x"}, data="<a:a> <a:b> <a:c> .",
                                         headers={"Content-Type": "application/n-triples"}),
                    lambda: requests.post(f"{serving.url}/store", params={"graph": "urn:x"},
                                          data="<a:a> <a:b> <a:c> .", headers={"Content-Type": "application/n-triples"}),
                    lambda: requests.delete(f"{serving.url}/store", params={"graph": "urn:x"})):
        response = request()
        assert response.status_code == 403 and "read-only" in response.text
    assert serving.count() == before  # nothing changed
    graph = requests.get(f"{serving.url}/store", params={"graph": "https://w3id.org/stepnc-graph/data/shaft_two_setups"
                                                                   ".stp"}, headers={"Accept": "application/n-triples"})
    program = "https://w3id.org/stepnc-graph/data/shaft_two_setups.stp"
    counted = serving.query(f"SELECT (COUNT(*) AS ?n) WHERE {{ GRAPH <{program}> {{ ?s ?p ?o }} }}")
    assert graph.status_code == 200 and graph.text.count("\n") == int(counted.json()["results"]["bindings"][0]["n"]
                                                                          ["value"])


def test_new_loads_are_served_once_published(serving: Serving, store: Path) -> None:
    before = serving.count()
    with sg.open_store(store) as s:  # a writer while serve runs: not blocked by it
        [r] = sg.load(s, [DAMAGED], lenient=True)
    for _ in range(100):
        if serving.count() > before:
            break
        time.sleep(0.1)
    assert serving.count() == before + r.triples + r.derived_triples


def test_result_size_limit_and_timeout(store: Path, tmp_path: Path) -> None:
    server = Serving(store, "--max-bytes", "2000", "--timeout", "1")
    try:
        small = server.query("SELECT ?s WHERE { GRAPH ?g { ?s a ?c } } LIMIT 2")
        assert small.status_code == 200
        big = server.query("SELECT * WHERE { GRAPH ?g { ?s ?p ?o } }")
        assert big.status_code == 507 and "larger than 2000 bytes" in big.text
        started = time.monotonic()
        slow = server.query("SELECT (COUNT(*) AS ?n) WHERE { GRAPH ?g { ?a ?b ?c . ?d ?e ?f . ?h ?i ?j } }")
        assert slow.status_code >= 400 and time.monotonic() - started < 30
    finally:
        server.stop()


def test_sigterm_stops_cleanly_and_the_store_is_intact(store: Path) -> None:
    server = Serving(store)
    count = server.count()
    code, stderr = server.stop(signal.SIGTERM)
    assert code == 0 and "Traceback" not in stderr
    with sg.open_store(store) as s:  # a writer gets the store
        assert s.count() == count
        sg.load(s, [DAMAGED], lenient=True)


def test_writable_serve_publishes_its_updates(store: Path) -> None:
    server = Serving(store, "--writable")
    try:
        update = requests.post(f"{server.url}/update", data='INSERT DATA { GRAPH <urn:note> { <urn:a> <urn:b> "c" } }',
                               headers={"Content-Type": "application/sparql-update"})
        assert update.status_code == 204
        with pytest.raises(sg.api.StoreBusy):  # the writer's lock is held while serving
            sg.open_store(store)
    finally:
        code, stderr = server.stop()
    assert code == 0 and "--writable" in stderr  # the warning
    with sg.open_store(store, readonly=True) as r:
        assert "urn:note" in r.graphs()


def test_a_killed_writable_serve_keeps_its_updates(store: Path) -> None:
    server = Serving(store, "--writable")
    requests.post(f"{server.url}/update", data='INSERT DATA { GRAPH <urn:kept> { <urn:a> <urn:b> "c" } }',
                  headers={"Content-Type": "application/sparql-update"})
    server.stop(signal.SIGKILL)
    for _ in range(100):  # its Oxigraph child follows it (parent-death signal) and releases the database
        try:
            with sg.open_store(store) as s:
                assert "urn:kept" in s.graphs()
            return
        except sg.api.StoreError:
            time.sleep(0.1)
    pytest.fail("the store could not be opened after serve was killed")


def test_a_non_loopback_host_must_be_asked_for_and_warns(store: Path) -> None:
    res = subprocess.run([*CLI, "serve", "--help"], capture_output=True, text=True)
    assert "127.0.0.1" in res.stdout
    server = Serving(store, "--host", "0.0.0.0")
    code, stderr = server.stop()
    assert "warning: listening on 0.0.0.0" in stderr
