"""`stepnc-graph serve`, tested with real HTTP requests against the running command."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import requests

import stepnc_graph as sg
from stepnc_graph.core.naming import listed_graphs

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

    def __init__(self, store: Path, *options: str, address: str = "127.0.0.1") -> None:
        try:
            from stepnc_graph.server.serve import oxigraph_binary

            oxigraph_binary()
        except Exception as e:  # noqa: BLE001 -- the reason is the skip message
            pytest.skip(f"serve cannot run here: {e}")
        self.port = free_port()
        self.url = f"http://{f'[{address}]' if ':' in address else address}:{self.port}"
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
            sg.open_store(store, readonly=False)
    finally:
        code, stderr = server.stop()
    assert code == 0 and "--writable" in stderr  # the warning
    with sg.open_store(store, readonly=True) as r:
        assert "urn:note" in listed_graphs(r)


def test_a_killed_writable_serve_keeps_its_updates(store: Path) -> None:
    server = Serving(store, "--writable")
    requests.post(f"{server.url}/update", data='INSERT DATA { GRAPH <urn:kept> { <urn:a> <urn:b> "c" } }',
                  headers={"Content-Type": "application/sparql-update"})
    server.stop(signal.SIGKILL)
    for _ in range(100):  # its Oxigraph child follows it (parent-death signal) and releases the database
        try:
            with sg.open_store(store, readonly=False) as s:  # the next writer publishes what it served
                assert "urn:kept" in listed_graphs(s)
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


def raw(port: int, request: bytes, address: str = "127.0.0.1", wait: float = 15) -> bytes:
    """Send ``request`` as it is over a socket; what came back before the server closed or ``wait`` passed."""
    with socket.create_connection((address, port), timeout=wait) as conn:
        conn.sendall(request)
        chunks = []
        try:
            while chunk := conn.recv(65536):
                chunks.append(chunk)
                if b"\r\n\r\n" in b"".join(chunks) and b"Connection: close" not in b"".join(chunks):
                    break
        except TimeoutError:
            pass
    return b"".join(chunks)


def test_a_request_naming_another_host_or_from_another_site_is_refused(serving: Serving) -> None:
    query = {"query": "ASK { ?s ?p ?o }"}
    for host in (f"localhost:{serving.port}", f"127.0.0.1:{serving.port}", "127.0.0.1", "LOCALHOST."):
        assert requests.get(f"{serving.url}/query", params=query, headers={"Host": host}).status_code == 200, host
    for host in ("attacker.example", f"attacker.example:{serving.port}", "localhost.attacker.example"):
        rebound = requests.get(f"{serving.url}/query", params=query, headers={"Host": host})  # DNS rebinding
        assert rebound.status_code == 421 and "--allow-host" in rebound.text, (host, rebound.text)
    for headers in ({"Origin": "https://attacker.example"}, {"Origin": "null"}, {"Sec-Fetch-Site": "cross-site"}):
        assert requests.get(f"{serving.url}/query", params=query, headers=headers).status_code == 403, headers
    same = requests.get(f"{serving.url}/query", params=query, headers={"Origin": serving.url})
    assert same.status_code == 200
    no_host = raw(serving.port, b"GET /query?query=ASK%7B%7D HTTP/1.1\r\nConnection: close\r\n\r\n")
    assert no_host.startswith(b"HTTP/1.1 400") and b"Host header" in no_host


def test_allow_host_adds_a_name(store: Path) -> None:
    server = Serving(store, "--allow-host", "sparql.example.org")
    try:
        response = requests.get(f"{server.url}/query", params={"query": "ASK {}"},
                                headers={"Host": "sparql.example.org"})
        assert response.status_code == 200
    finally:
        server.stop()


def test_request_bodies_are_bounded_and_their_length_checked(serving: Serving) -> None:
    started = time.monotonic()
    huge = raw(serving.port, b"POST /query HTTP/1.1\r\nHost: localhost\r\nContent-Type: application/sparql-query"
                             b"\r\nContent-Length: 400000000\r\n\r\nASK {")
    assert huge.startswith(b"HTTP/1.1 413") and b"--max-request-bytes" in huge, huge
    assert time.monotonic() - started < 10  # answered at once, not after reading 400 MB
    for length in (b"-5", b"abc", b"1e3", b"5, 6"):
        answer = raw(serving.port, b"POST /query HTTP/1.1\r\nHost: localhost\r\nContent-Type: "
                                   b"application/sparql-query\r\nContent-Length: " + length + b"\r\n\r\nASK {}")
        assert answer.startswith(b"HTTP/1.1 400") and b"Content-Length" in answer, (length, answer)
    chunked = raw(serving.port, b"POST /query HTTP/1.1\r\nHost: localhost\r\nContent-Type: application/sparql-query"
                                b"\r\nTransfer-Encoding: chunked\r\n\r\n6\r\nASK {}\r\n0\r\n\r\n")
    assert chunked.startswith(b"HTTP/1.1 411"), chunked
    assert serving.query("ASK {}").status_code == 200  # still serving
    code, stderr = serving.stop()
    assert "Traceback" not in stderr, stderr


def test_max_request_bytes_sets_the_limit(store: Path) -> None:
    server = Serving(store, "--max-request-bytes", "1000")
    try:
        assert server.query("ASK {}" + " " * 900).status_code == 200
        over = server.query("ASK {}" + " " * 2000)
        assert over.status_code == 413 and "larger than 1000 bytes" in over.text
    finally:
        server.stop()


def test_ipv6_loopback(store: Path) -> None:
    if not socket.has_ipv6:
        pytest.skip("no IPv6 here")
    try:
        with socket.socket(socket.AF_INET6) as probe:
            probe.bind(("::1", 0))
    except OSError:
        pytest.skip("no IPv6 loopback here")
    server = Serving(store, "--host", "::1", address="::1")
    try:
        response = requests.get(f"{server.url}/query", params={"query": "ASK {}"})
        assert response.status_code == 200
    finally:
        code, stderr = server.stop()
    assert code == 0 and "warning: listening" not in stderr and "Traceback" not in stderr, stderr


def test_a_client_that_goes_away_is_no_traceback(serving: Serving) -> None:
    body = b"query=SELECT%20*%20WHERE%20%7B%20GRAPH%20%3Fg%20%7B%20%3Fs%20%3Fp%20%3Fo%20%7D%20%7D"
    for _ in range(5):
        with socket.create_connection(("127.0.0.1", serving.port)) as conn:
            conn.sendall(b"POST /query HTTP/1.1\r\nHost: localhost\r\nContent-Type: application/x-www-form-urlencoded"
                         b"\r\nContent-Length: " + str(len(body)).encode() + b"\r\n\r\n" + body)
            conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")  # reset
    time.sleep(1.5)
    assert serving.count() > 0
    code, stderr = serving.stop()
    assert "Traceback" not in stderr and "BrokenPipe" not in stderr and "ConnectionReset" not in stderr, stderr


class _Federated(threading.Thread):
    """A loopback SPARQL endpoint for SERVICE calls: answers with ``reply``, or never (``reply`` None)."""

    def __init__(self, reply: bytes | None) -> None:
        super().__init__(daemon=True)
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.url = f"http://127.0.0.1:{self.sock.getsockname()[1]}/sparql"
        self.reply = reply
        self.held: list[socket.socket] = []
        self.start()

    def run(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            conn.recv(65536)
            if self.reply is None:
                self.held.append(conn)  # never answers
            else:
                conn.sendall(self.reply)
                conn.close()


def test_an_error_while_the_result_is_written_is_no_200(store: Path) -> None:
    body = b'{"head": {"vars": ["s"]}, "results": {"bindings": [{"s": {"type": "uri", "value": "urn:a"}}'  # cut short
    broken = _Federated(b"HTTP/1.1 200 OK\r\nContent-Type: application/sparql-results+json\r\nContent-Length: "
                        + str(len(body)).encode() + b"\r\n\r\n" + body)
    server = Serving(store, "--allow-service")
    try:
        for accept in ("application/sparql-results+json", "text/csv", "text/tab-separated-values"):
            response = requests.post(f"{server.url}/query", data={"query": "SELECT * WHERE { ?x ?y ?z } LIMIT 1 "},
                                     headers={"Accept": accept})
            assert response.status_code == 200
            response = requests.post(f"{server.url}/query", headers={"Accept": accept}, data={
                "query": f"SELECT ?s WHERE {{ VALUES ?n {{ 1 2 }} SERVICE <{broken.url}> {{ ?s ?p ?o }} }}"})
            assert response.status_code == 500 and "failed while writing the result" in response.text, \
                (accept, response.status_code, response.text)
    finally:
        code, stderr = server.stop()
    assert "--allow-service" in stderr  # the warning


def test_the_timeout_bounds_a_service_call(store: Path) -> None:
    hanging = _Federated(None)
    server = Serving(store, "--allow-service", "--timeout", "2")
    try:
        started = time.monotonic()
        response = server.query(f"SELECT * WHERE {{ SERVICE <{hanging.url}> {{ ?s ?p ?o }} }}")
        assert response.status_code == 503 and "took longer than 2 s" in response.text
        assert time.monotonic() - started < 15
    finally:
        server.stop()


def _library_store(tmp_path: Path) -> Path:
    """A store of the example and the seed programs (several programs: whole-store answers)."""
    path = tmp_path / "library-store"
    with sg.open_store(path) as s:
        sg.load(s, [EXAMPLE, *sorted((ROOT / "tests" / "fixtures" / "p21").glob("pass_*.stp"))])
    return path


def _rdflib_text(term: dict[str, str] | None) -> str:
    """A SPARQL JSON term as rdflib shows it (rdflib normalises a literal's lexical form)."""
    from rdflib import Literal

    if term is None:
        return ""
    if term["type"] == "literal":
        return str(Literal(term["value"], datatype=term.get("datatype"), lang=term.get("xml:lang")))
    return term["value"]


def test_standard_clients_get_the_library_answers_with_no_dataset_recipe(tmp_path: Path) -> None:
    """SPARQLWrapper and rdflib's SPARQLStore send each library query as written; the rows are
    those `stepnc-graph query` gives (the service's default dataset is the one the library is
    written for), and the service description names the address clients use."""
    from rdflib.plugins.stores.sparqlstore import SPARQLStore
    from SPARQLWrapper import JSON as WRAPPER_JSON, SPARQLWrapper

    from stepnc_graph.querying.query import library, query

    path = _library_store(tmp_path)
    expected: dict[str, list[list[str]]] = {}
    as_rdflib: dict[str, list[list[str]]] = {}
    with sg.open_store(path, readonly=True) as s:
        for q in library():
            params = {"tool_type": "grooving_tool"} if q.params else {}
            result = json.loads(query(s, q.name, **params).serialize("json"))
            expected[q.name] = [[row.get(v, {}).get("value", "") for v in result["head"]["vars"]]
                                for row in result["results"]["bindings"]]
            as_rdflib[q.name] = [[_rdflib_text(row.get(v)) for v in result["head"]["vars"]]
                                 for row in result["results"]["bindings"]]
    server = Serving(path)
    try:
        rdflib_store = SPARQLStore(f"{server.url}/query", returnFormat="json")
        for q in library():
            if q.params:
                continue
            wrapper = SPARQLWrapper(f"{server.url}/query")
            wrapper.setQuery(q.text)  # SPARQLWrapper takes "Loading" in a comment for LOAD: sent as an update
            wrapper.setReturnFormat(WRAPPER_JSON)
            document = wrapper.query().convert()
            rows = [[row.get(v, {}).get("value", "") for v in document["head"]["vars"]]
                    for row in document["results"]["bindings"]]
            assert rows == expected[q.name], q.name
            answer = rdflib_store.query(q.text)  # rdflib writes a literal's value its own way ("15" as 15.0)
            assert [["" if t is None else str(t) for t in row] for row in answer] == as_rdflib[q.name], q.name
        description = requests.get(f"{server.url}/query", headers={"Accept": "application/n-triples"}, timeout=30)
        assert description.status_code == 200
        assert f"<{server.url}/query>" in description.text, description.text[:500]
        turtle = requests.get(f"{server.url}/query", headers={"Accept": "text/turtle"}, timeout=30)
        assert turtle.status_code == 200 and "sd:Service" in turtle.text
        sample = server.query("SELECT * WHERE { ?s ?p ?o } LIMIT 10")  # the web page's pre-filled query
        assert len(sample.json()["results"]["bindings"]) == 10
    finally:
        server.stop()
