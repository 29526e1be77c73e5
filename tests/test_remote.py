"""Remote stores over the standard protocols, tested against a real Oxigraph server.

The server is `oxigraph serve` from the `oxigraph` PyPI package (a test dependency), started
on a free loopback port and stopped by its pid. Everything the embedded store answers, the
remote one must answer the same.
"""

from __future__ import annotations

import http.server
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

import stepnc_graph as sg
from stepnc_graph.remote import Endpoint, RemoteStore, StoreError, open_remote

from conftest import FIXTURES, ROOT
from oxigraph_server import OxigraphServer, ServerUnavailable, free_port

pytestmark = pytest.mark.usefixtures("process_time_bound")

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
PROGRAMS = [EXAMPLE, *sorted((FIXTURES / "p21").glob("pass_*.stp"))]
CLI = [sys.executable, "-m", "stepnc_graph.cli"]


@pytest.fixture
def server(tmp_path: Path) -> Iterator[OxigraphServer]:
    srv = OxigraphServer(tmp_path / "server-data")
    try:
        srv.start()
    except ServerUnavailable as exc:
        pytest.skip(str(exc))
    yield srv
    srv.stop()


def cli(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "SOURCE_DATE_EPOCH": "1700000000", **(env or {})})


def test_the_same_answers_as_the_embedded_store(server: OxigraphServer, tmp_path: Path) -> None:
    local = str(tmp_path / "local")
    for program in PROGRAMS:
        assert cli("load", "--endpoint", server.url, str(program)).returncode == 0
        assert cli("load", "--store", local, str(program)).returncode == 0
    remote_info = json.loads(cli("info", "--endpoint", server.url, "--format", "json").stdout)["graphs"]
    local_info = json.loads(cli("info", "--store", local, "--format", "json").stdout)["graphs"]
    assert [{k: v for k, v in g.items() if k != "loaded"} for g in remote_info] == \
        [{k: v for k, v in g.items() if k != "loaded"} for g in local_info]
    assert len(remote_info) == len(PROGRAMS)
    graph = "https://w3id.org/stepnc-graph/data/shaft_two_setups.stp"
    for fmt in ("p21", "ttl", "jsonld"):
        remote = cli("export", "--endpoint", server.url, "--format", fmt, "--graph", graph)
        assert remote.returncode == 0, remote.stderr
        assert remote.stdout == cli("export", "--store", local, "--format", fmt, "--graph", graph).stdout
    with open_remote(server.url) as store, sg.open_store(local, readonly=True) as embedded:
        sparql = ("SELECT ?g (COUNT(*) AS ?n) WHERE { GRAPH ?g { ?s a ?c } } GROUP BY ?g ORDER BY ?g")
        assert [tuple(str(t) for t in row) for row in store.query(sparql)] == \
            [tuple(str(t) for t in row) for row in embedded.query(sparql)]
    assert cli("unload", "--endpoint", server.url, graph).returncode == 0
    assert graph not in cli("info", "--endpoint", server.url).stdout


def test_endpoint_from_the_environment_and_option_conflicts(server: OxigraphServer, tmp_path: Path) -> None:
    env = {"STEPNC_GRAPH_ENDPOINT": server.url}
    assert cli("load", str(EXAMPLE), env=env).returncode == 0
    assert "shaft_two_setups.stp" in cli("info", env=env).stdout
    assert "0 graph(s)" in cli("info", "--store", str(tmp_path / "s"), env=env).stdout or \
        cli("info", "--store", str(tmp_path / "s"), env=env).returncode == 2  # --store wins over the variable
    both = cli("info", "--endpoint", server.url, "--store", str(tmp_path / "s"))
    assert both.returncode == 2 and "exclude each other" in both.stderr


def _big(tmp_path: Path) -> Path:
    sys.path.insert(0, str(ROOT / "bench"))
    from generate import write  # type: ignore[import-not-found]

    path = tmp_path / "big.stp"
    write(60_000, path)
    return path


def test_killing_the_server_mid_load_keeps_the_previous_graph(server: OxigraphServer, tmp_path: Path) -> None:
    graph = "https://plm.example.org/programs/42"
    assert cli("load", "--endpoint", server.url, "--base-iri", graph, str(EXAMPLE)).returncode == 0
    with open_remote(server.url) as store:
        before = store.count(graph)
    child = subprocess.Popen([*CLI, "load", "--endpoint", server.url, "--base-iri", graph, "--replace",
                              str(_big(tmp_path))],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env={**os.environ, "STEPNC_GRAPH_RETRIES": "1"})
    time.sleep(2.0)
    assert child.poll() is None, "the load ended before the server could be killed"
    server.stop(signal.SIGKILL)
    _, stderr = child.communicate(timeout=120)
    assert child.returncode == 2 and "Traceback" not in stderr and "does not answer" in stderr, stderr
    server.start()  # the same data directory
    with open_remote(server.url) as store:
        assert store.count(graph) == before
        assert store.graphs() == [graph]  # a staging graph left behind is not a program


def test_credentials_come_from_the_environment_and_are_never_in_urls(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(StoreError, match="must not hold a user or password"):
        Endpoint.from_options("https://alice:secret@example.org/sparql")
    seen: list[dict[str, str]] = []

    class Handler(http.server.BaseHTTPRequestHandler):
        def do_POST(self) -> None:  # noqa: N802 -- the http.server API
            seen.append(dict(self.headers))
            self.rfile.read(int(self.headers.get("Content-Length", 0)))
            body = json.dumps({"head": {}, "boolean": True}).encode()
            self.send_response(200)
            self.send_header("Content-Type", "application/sparql-results+json")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: object) -> None:
            pass

    httpd = http.server.HTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        monkeypatch.setenv("STEPNC_GRAPH_ENDPOINT_TOKEN", "t0ken")
        with open_remote(f"http://127.0.0.1:{httpd.server_address[1]}") as store:
            assert seen[-1]["Authorization"] == "Bearer t0ken"
            assert "t0ken" not in repr(store.endpoint) and "t0ken" not in str(store.endpoint)
        monkeypatch.delenv("STEPNC_GRAPH_ENDPOINT_TOKEN")
        monkeypatch.setenv("STEPNC_GRAPH_ENDPOINT_USER", "alice")
        monkeypatch.setenv("STEPNC_GRAPH_ENDPOINT_PASSWORD", "secret")
        open_remote(f"http://127.0.0.1:{httpd.server_address[1]}").close()
        assert seen[-1]["Authorization"].startswith("Basic ")
    finally:
        httpd.shutdown()


def test_an_endpoint_that_does_not_answer_is_a_clean_error() -> None:
    res = subprocess.run([*CLI, "info", "--endpoint", f"http://127.0.0.1:{free_port()}"], capture_output=True,
                         text=True, env={**os.environ, "STEPNC_GRAPH_RETRIES": "0"}, timeout=60)
    assert res.returncode == 2 and "does not answer" in res.stderr and "Traceback" not in res.stderr


def test_remote_store_is_a_store(server: OxigraphServer) -> None:
    with open_remote(server.url) as store:
        assert isinstance(store, RemoteStore)
        [r] = sg.load(store, [EXAMPLE])
        assert store.graphs() == [r.graph] and store.count(r.graph) == r.triples
        assert sg.unload(store, r.graph) and not store.has_graph(r.graph)
