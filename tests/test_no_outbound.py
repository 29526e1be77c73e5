"""No SPARQL a user hands stepnc-graph makes it send a request elsewhere unless asked (SERVICE, LOAD).

Every test points the SERVICE clause (or LOAD) at a real loopback listener started here, which
must receive nothing: query (-e, a .rq file, standard input, the Python API, --endpoint),
validate (an sh:sparql constraint, directly and inside a nested shape) and serve (the query
parameter of GET and POST, form and direct bodies, /sparql, updates when --writable).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
import requests

import stepnc_graph as sg
from stepnc_graph.querying.query import QueryError
from stepnc_graph.validation import ShapesError

from conftest import ROOT

pytestmark = pytest.mark.usefixtures("process_time_bound")

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"
CLI = [sys.executable, "-m", "stepnc_graph.cli"]
STEPNC = "https://w3id.org/stepnc-graph/iso14649#"


class Listener:
    """A TCP server on a free loopback port that records every connection (and what it was sent);
    it answers with ``reply`` (an HTTP response), or closes at once."""

    def __init__(self, reply: bytes = b"") -> None:
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.port = int(self.sock.getsockname()[1])
        self.url = f"http://127.0.0.1:{self.port}/sparql"
        self.received: list[bytes] = []
        self.reply = reply
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            with conn:
                conn.settimeout(2)
                try:
                    self.received.append(conn.recv(65536))
                    if self.reply:
                        conn.sendall(self.reply)
                except OSError:
                    self.received.append(b"")

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def listener() -> Iterator[Listener]:
    server = Listener()
    yield server
    server.close()


def cli(*args: str, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=120, input=stdin,
                          env={**os.environ, "STEPNC_GRAPH_RETRIES": "0"})


def evasions(url: str) -> list[str]:
    """SERVICE clauses as a hostile query would write them."""
    return [
        f"SELECT * WHERE {{ SERVICE <{url}> {{ ?s ?p ?o }} }}",
        f"select * where {{ sErViCe <{url}> {{ ?s ?p ?o }} }}",
        f"SELECT * WHERE {{ SERVICE # a comment with }} and \"quotes\n <{url}> {{ ?s ?p ?o }} }}",
        f"SELECT * WHERE {{ SERVICE SILENT <{url}> {{ ?s ?p ?o }} }}",
        f"PREFIX e: <{url}> SELECT * WHERE {{ OPTIONAL {{ {{ SELECT ?s WHERE {{ SERVICE e: {{ ?s ?p ?o }} }} }} }} }}",
        f"SELECT * WHERE {{ BIND(<{url}> AS ?at) SERVICE ?at {{ ?s ?p ?o }} }}",
        f"SELECT * WHERE {{ ?a ?b ?c FILTER EXISTS {{ SERVICE <{url}> {{ ?s ?p ?o }} }} }}",
    ]


def harmless(url: str) -> list[str]:
    """Texts that mention SERVICE without calling it: they must run."""
    return [
        f'SELECT ?x WHERE {{ BIND("SERVICE <{url}> {{ ?s ?p ?o }}" AS ?x) }}',
        f"# SERVICE <{url}> {{ ?s ?p ?o }}\nSELECT ?x WHERE {{ BIND(1 AS ?x) }}",
        "PREFIX service: <urn:x:> SELECT ?x WHERE { BIND(service:SERVICE AS ?x) }",
        f"SELECT ?x WHERE {{ BIND(<{url}#SERVICE> AS ?x) }}",
    ]


# -- the check itself ---------------------------------------------------------------------


def test_the_check_reads_the_parse_tree_not_the_letters() -> None:
    from stepnc_graph.core.outbound import OutboundRefused, outbound_keyword, refuse_outbound

    url = "http://127.0.0.1:9/sparql"
    for text in evasions(url):
        assert outbound_keyword(text) is not None, text
        with pytest.raises(OutboundRefused, match="SERVICE is refused.*--allow-service allows it"):
            refuse_outbound(text)
        refuse_outbound(text, allow=True)
    for text in harmless(url):
        assert outbound_keyword(text) is None, text
    assert outbound_keyword(f"LOAD <{url}>", update=True) == ("LOAD", "")
    assert outbound_keyword(f"INSERT {{ ?s ?p ?o }} WHERE {{ SERVICE <{url}> {{ ?s ?p ?o }} }}", update=True)
    assert outbound_keyword('INSERT DATA { <urn:a> <urn:b> "upload" }', update=True) is None
    # codepoint escapes (SPARQL 1.1, 19.2) cannot hide the keyword from the check
    assert outbound_keyword(f"SELECT * WHERE {{ \\u0053ERVICE <{url}> {{ ?s ?p ?o }} }}") is not None
    # a text that mentions SERVICE and does not parse cannot be shown harmless: refused
    found = outbound_keyword(f"SELECT * WHERE {{ SERVICE <{url}> {{ ?s ?p ?o ")
    assert found is not None and "cannot read it at line 1" in found[1]


# -- query ----------------------------------------------------------------------------------


def test_query_refuses_service_from_every_source(listener: Listener, tmp_path: Path) -> None:
    for text in evasions(listener.url):
        res = cli("query", "-e", text, str(EXAMPLE))
        assert res.returncode == 2 and "SERVICE is refused" in res.stderr and "--allow-service" in res.stderr, \
            (text, res.stderr)
        assert "Traceback" not in res.stderr
    rq = tmp_path / "federated.rq"
    rq.write_text(f"# title: federated\n{evasions(listener.url)[0]}\n", encoding="utf-8")
    res = cli("query", str(rq), str(EXAMPLE))
    assert res.returncode == 2 and f"{rq}: SERVICE is refused" in res.stderr, res.stderr
    res = cli("query", "-", str(EXAMPLE), stdin=evasions(listener.url)[1])
    assert res.returncode == 2 and "<stdin>: SERVICE is refused" in res.stderr, res.stderr
    with sg.open_store(memory=True) as store:
        sg.load(store, [EXAMPLE])
        with pytest.raises(QueryError, match="SERVICE is refused"):
            sg.query(store, evasions(listener.url)[0])
    assert listener.received == []


def test_query_runs_what_only_mentions_service(listener: Listener) -> None:
    for text in harmless(listener.url):
        res = cli("query", "-e", text, str(EXAMPLE), "--format", "csv")
        assert res.returncode == 0, (text, res.stderr)
    assert listener.received == []


def test_allow_service_is_an_opt_in_that_warns(listener: Listener) -> None:
    res = cli("query", "--allow-service", "-e", f"SELECT * WHERE {{ SERVICE SILENT <{listener.url}> {{ ?s ?p ?o }} }}",
              str(EXAMPLE))
    assert res.returncode == 0 and "warning: --allow-service" in res.stderr, res.stderr
    assert len(listener.received) == 1 and listener.received[0].startswith(b"POST /sparql")


# -- validate -------------------------------------------------------------------------------


def _shapes(tmp_path: Path, url: str, nested: bool) -> Path:
    sparql = (f'sh:sparql [ sh:message "federated" ; sh:select """SELECT $this WHERE {{ '
              f'SERVICE <{url}> {{ $this ?p ?o }} }}""" ]')
    if nested:  # the SPARQL constraint compiled into another shape's expression (sh:node)
        body = f"sh:targetClass stepnc:workingstep ; sh:node [ a sh:NodeShape ; {sparql} ] ."
    else:
        body = f"sh:targetClass stepnc:workingstep ; {sparql} ."
    path = tmp_path / f"federated-{nested}.ttl"
    path.write_text(f"@prefix sh: <http://www.w3.org/ns/shacl#> .\n@prefix stepnc: <{STEPNC}> .\n"
                    f"@prefix ex: <urn:example:> .\nex:Federated a sh:NodeShape ; {body}\n", encoding="utf-8")
    return path


def test_validate_refuses_service_in_shapes(listener: Listener, tmp_path: Path) -> None:
    for nested in (False, True):
        shapes = _shapes(tmp_path, listener.url, nested)
        res = cli("validate", "--shapes", str(shapes), str(EXAMPLE))
        assert res.returncode == 2 and "SERVICE is refused" in res.stderr and "--allow-service" in res.stderr, \
            res.stderr
        assert "Traceback" not in res.stderr
        with pytest.raises(ShapesError, match="SERVICE is refused"):  # the API too
            sg.validate([EXAMPLE], extra_shapes=[shapes])
    assert listener.received == []
    res = cli("validate", "--allow-service", "--shapes", str(_shapes(tmp_path, listener.url, False)), str(EXAMPLE))
    assert "warning: --allow-service" in res.stderr and "Traceback" not in res.stderr, res.stderr
    assert listener.received, "the opt-in did not let the SERVICE call through"


# -- serve ----------------------------------------------------------------------------------


@pytest.fixture
def served(tmp_path: Path) -> Iterator[Path]:
    store = tmp_path / "store"
    with sg.open_store(store) as s:
        sg.load(s, [EXAMPLE])
    yield store


def test_serve_refuses_service_however_it_is_sent(listener: Listener, served: Path) -> None:
    from test_serve import Serving

    server = Serving(served)
    try:
        query = evasions(listener.url)[0]
        attempts = [
            requests.get(f"{server.url}/query", params={"query": query}),  # what a web page's <img> can send
            requests.post(f"{server.url}/query", data={"query": query}),
            requests.post(f"{server.url}/query", data=query.encode(),
                          headers={"Content-Type": "application/sparql-query"}),
            requests.post(f"{server.url}/query", data=query.encode(),
                          headers={"Content-Type": "Application/SPARQL-Query ; charset=utf-8"}),
            requests.post(f"{server.url}/sparql", data={"query": query}),
            requests.head(f"{server.url}/query", params={"query": query}),
        ] + [requests.get(f"{server.url}/query", params={"query": text}) for text in evasions(listener.url)[1:]]
        for response in attempts:
            assert response.status_code == 403, (response.request.url, response.status_code, response.text)
            assert response.request.method == "HEAD" or "SERVICE is refused" in response.text
        # a second query parameter (which one would Oxigraph run?) is refused outright
        two = requests.get(f"{server.url}/query?query=ASK%7B%7D&query={requests.utils.quote(query)}")
        assert two.status_code == 400 and "one query" in two.text
        mixed = requests.post(f"{server.url}/query?query=ASK%7B%7D", data={"query": query})
        assert mixed.status_code == 400
        ok = requests.get(f"{server.url}/query", params={"query": harmless(listener.url)[0]},
                          headers={"Accept": "application/sparql-results+json"})
        assert ok.status_code == 200 and "SERVICE" in ok.text
    finally:
        code, stderr = server.stop()
    assert listener.received == []
    assert "Traceback" not in stderr


def test_writable_serve_refuses_service_and_load_in_updates(listener: Listener, served: Path) -> None:
    from test_serve import Serving

    server = Serving(served, "--writable")
    try:
        for update in (f"LOAD <{listener.url}>", f"load silent <{listener.url}> INTO GRAPH <urn:g>",
                       f"INSERT {{ GRAPH <urn:g> {{ ?s ?p ?o }} }} WHERE {{ SERVICE <{listener.url}> {{ ?s ?p ?o }} }}"):
            for response in (requests.post(f"{server.url}/update", data={"update": update}),
                             requests.post(f"{server.url}/update", data=update.encode(),
                                           headers={"Content-Type": "application/sparql-update"})):
                assert response.status_code == 403, (update, response.text)
                assert "is refused" in response.text
        done = requests.post(f"{server.url}/update", data='INSERT DATA { GRAPH <urn:g> { <urn:a> <urn:b> "c" } }',
                             headers={"Content-Type": "application/sparql-update"})
        assert done.status_code == 204
    finally:
        server.stop()
    assert listener.received == []


def test_query_over_an_endpoint_refuses_service_before_sending(listener: Listener, tmp_path: Path) -> None:
    from oxigraph_server import OxigraphServer, ServerUnavailable

    remote = OxigraphServer(tmp_path / "remote")
    try:
        remote.start()
    except ServerUnavailable as exc:
        pytest.skip(str(exc))
    try:
        res = cli("query", "--endpoint", remote.url, "-e", evasions(listener.url)[0])
        assert res.returncode == 2 and "SERVICE is refused" in res.stderr, res.stderr
    finally:
        remote.stop()
    assert listener.received == []  # the remote server was never asked to call it
