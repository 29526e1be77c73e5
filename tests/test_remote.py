"""Remote stores over the standard protocols, tested against a real Oxigraph server.

The server is `oxigraph serve` from the `oxigraph` PyPI package (a test dependency), started
on a free loopback port and stopped by its pid. Everything the embedded store answers, the
remote one must answer the same.
"""

from __future__ import annotations

import base64
import http.server
import json
import os
import re
import shutil
import signal
import ssl
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

import stepnc_graph as sg
from stepnc_graph.store import remote_load
from stepnc_graph.store.remote import _STAGING_NAME, Endpoint, RemoteStore, StoreError, open_remote
from stepnc_graph.core.naming import STAGING, listed_graphs

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
        assert listed_graphs(store) == [graph]  # a staging graph left behind is not a program


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
        assert listed_graphs(store) == [r.graph] and store.count(r.graph) == r.triples
        assert sg.unload(store, r.graph) and not store.has_graph(r.graph)


# -- answers that are not what was asked for, hanging endpoints, TLS, credentials, parameters ------


class _Fake(http.server.BaseHTTPRequestHandler):
    """An endpoint whose answers a test chooses: ``answer(query_text) -> (status, content type, body)``,
    or None to keep silent (until the test ends)."""

    answer: Any = None
    seen: list[tuple[str, str, dict[str, str]]] = []

    def do_POST(self) -> None:  # noqa: N802 -- the http.server API
        from urllib.parse import parse_qs

        body = self.rfile.read(int(self.headers.get("Content-Length", 0))).decode()
        text = parse_qs(body).get("query", [body])[0] if "form" in self.headers.get("Content-Type", "") else body
        self.seen.append((self.path, text, dict(self.headers)))
        reply = type(self).answer(self.path, text, dict(self.headers))
        if reply is None:
            time.sleep(30)
            return
        status, media_type, data = reply
        self.send_response(status)
        self.send_header("Content-Type", media_type)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def log_message(self, *args: object) -> None:
        pass


@contextmanager
def fake_endpoint(answer: Any, server: str | None = None) -> Iterator[tuple[str, list[tuple[str, str, dict[str, str]]]]]:
    """``server``: the Server header it answers with (default: http.server's own)."""
    named = {} if server is None else {"server_version": server, "sys_version": ""}
    handler = type("Handler", (_Fake,), {"answer": staticmethod(answer), "seen": [], **named})
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    httpd.daemon_threads = True
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}", handler.seen
    finally:
        httpd.shutdown()
        httpd.server_close()


ASK_TRUE = (200, "application/sparql-results+json", b'{"head": {}, "boolean": true}')


def empty_store(path: str, text: str, headers: dict[str, str]) -> Any:
    """An empty store's answers to `info`: no rows, with the variables each SELECT projects."""
    if text.startswith("ASK"):
        return ASK_TRUE
    projected = re.search(r"SELECT\s+(?:DISTINCT\s+)?((?:\?\w+\s*)+)", text)
    names = re.findall(r"\?(\w+)", projected.group(1)) if projected else ["g"]
    return 200, "application/sparql-results+json", json.dumps({"head": {"vars": names},
                                                               "results": {"bindings": []}}).encode()


def test_an_unexpected_answer_is_a_clear_error(tmp_path: Path) -> None:
    html = (200, "text/html; charset=utf-8", b"<!DOCTYPE html><html><body><form>Sign in</form></body></html>")
    cut = (200, "application/sparql-results+json", b'{"head": {"vars": ["g"]}, "results": {"bindings": [{"g": {"ty')
    boolean = ASK_TRUE
    others = (200, "application/sparql-results+json",
              b'{"head": {"vars": ["x"]}, "results": {"bindings": [{"x": {"type": "uri", "value": "urn:x"}}]}}')
    cases = [(html, "an HTML page"), (cut, "does not parse"), (boolean, "a boolean where SPARQL results with ?g"),
             (others, "the variables ?x where SPARQL results with ?g")]
    for reply, expected in cases:
        with fake_endpoint(lambda path, text, headers, reply=reply: ASK_TRUE if text.startswith("ASK") else reply) \
                as (url, _):
            res = cli("info", "--endpoint", url, env={"STEPNC_GRAPH_RETRIES": "0"})
        assert res.returncode == 2 and expected in res.stderr and url.split("//")[1] in res.stderr, res.stderr
        assert "Traceback" not in res.stderr
    # an ASK answered with rows, and a CONSTRUCT answered with results
    with fake_endpoint(lambda path, text, headers: others if "ASK" in text else ASK_TRUE) as (url, _):
        res = cli("info", "--endpoint", url, env={"STEPNC_GRAPH_RETRIES": "0"})
    assert res.returncode == 2 and "rows where a boolean" in res.stderr and "Traceback" not in res.stderr, res.stderr


def test_a_hanging_endpoint_is_given_up_after_the_timeout() -> None:
    with fake_endpoint(lambda path, text, headers: None) as (url, seen):
        for args, env in ((["--timeout", "1"], {}), ([], {"STEPNC_GRAPH_TIMEOUT": "1"})):
            started = time.monotonic()
            res = cli("info", "--endpoint", url, *args, env=env)
            assert res.returncode == 2 and "did not answer within 1 s" in res.stderr, res.stderr
            assert time.monotonic() - started < 20 and "Traceback" not in res.stderr
        assert len(seen) == 2  # a read timeout is not retried (the default would try 6 times)
    bad = cli("info", "--endpoint", "http://127.0.0.1:9", env={"STEPNC_GRAPH_TIMEOUT": "soon"})
    assert bad.returncode == 2 and "STEPNC_GRAPH_TIMEOUT='soon'" in bad.stderr


def test_an_update_that_timed_out_is_not_sent_again() -> None:
    def answer(path: str, text: str, headers: dict[str, str]) -> Any:
        return None if path == "/update" else ASK_TRUE

    with fake_endpoint(answer) as (url, seen):
        with open_remote(url, timeout=1) as store:
            with pytest.raises(StoreError, match="did not answer within 1 s.*may have been carried out"):
                store.update("DROP SILENT GRAPH <urn:x>")
        assert [p for p, _, _ in seen].count("/update") == 1


def test_credentials_never_appear_in_a_message(monkeypatch: pytest.MonkeyPatch) -> None:
    def echo(path: str, text: str, headers: dict[str, str]) -> Any:  # a proxy's error page showing the request
        if text.startswith("ASK"):
            return ASK_TRUE
        return 400, "text/plain", "\n".join(f"{k}: {v}" for k, v in headers.items()).encode()

    with fake_endpoint(echo) as (url, _):
        monkeypatch.setenv("STEPNC_GRAPH_ENDPOINT_TOKEN", "s3cret-t0ken")
        res = cli("info", "--endpoint", url)
        assert res.returncode == 2 and "answered 400" in res.stderr and "s3cret-t0ken" not in res.stderr, res.stderr
        monkeypatch.delenv("STEPNC_GRAPH_ENDPOINT_TOKEN")
        monkeypatch.setenv("STEPNC_GRAPH_ENDPOINT_USER", "alice")
        monkeypatch.setenv("STEPNC_GRAPH_ENDPOINT_PASSWORD", "pa55word")
        res = cli("info", "--endpoint", url)
        basic = base64.b64encode(b"alice:pa55word").decode()
        assert res.returncode == 2 and "Authorization" in res.stderr, res.stderr
        assert basic not in res.stderr and "pa55word" not in res.stderr


def test_the_ca_bundle_of_stepnc_graph_wins_over_requests_own(tmp_path: Path) -> None:
    if shutil.which("openssl") is None:
        pytest.skip("no openssl to make a certificate")
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    made = subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out",
                           str(cert), "-days", "1", "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1"],
                          capture_output=True)
    if made.returncode != 0:
        pytest.skip(f"openssl cannot make a certificate: {made.stderr[-200:]!r}")
    other = tmp_path / "other.pem"  # a valid bundle that does not hold this server's certificate
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(tmp_path / "k2"),
                    "-out", str(other), "-days", "1", "-subj", "/CN=other"], capture_output=True, check=True)
    handler = type("Handler", (_Fake,), {"answer": staticmethod(empty_store), "seen": []})
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.load_cert_chain(cert, key)
    httpd.socket = context.wrap_socket(httpd.socket, server_side=True)
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    url = f"https://127.0.0.1:{httpd.server_address[1]}"
    corporate = {"REQUESTS_CA_BUNDLE": str(other), "CURL_CA_BUNDLE": str(other), "STEPNC_GRAPH_RETRIES": "0"}
    try:
        for env in ({**corporate, "STEPNC_GRAPH_CA_BUNDLE": str(cert)}, {"STEPNC_GRAPH_CA_BUNDLE": str(cert)},
                    {"REQUESTS_CA_BUNDLE": str(cert)}):
            res = cli("info", "--endpoint", url, env=env)
            assert res.returncode == 0, (env, res.stderr)
        res = cli("info", "--endpoint", url, env=corporate)  # the certificate is checked
        assert res.returncode == 2 and "TLS failed" in res.stderr and "Traceback" not in res.stderr, res.stderr
        res = cli("info", "--endpoint", url, env={"STEPNC_GRAPH_CA_BUNDLE": str(tmp_path / "missing.pem")})
        assert res.returncode == 2 and "does not exist" in res.stderr
    finally:
        httpd.shutdown()


BY_ID = """# title: Workingstep by id
# description: the workingsteps with an id, as a FILTER reads it (and one in a UNION branch)
# param: ws_id (string) = WS5 RELIEF GROOVE -- the workingstep's its_id
PREFIX attr: <https://w3id.org/stepnc-graph/attribute#>
SELECT ?ws ?ws_id ?how WHERE {
  { ?ws attr:its_operation ?op ; attr:its_id ?id FILTER(?id = ?ws_id) BIND("equal" AS ?how) }
  UNION
  { ?ws attr:its_operation ?op ; attr:its_id ?id FILTER(STRSTARTS(?id, SUBSTR(?ws_id, 1, 3))) BIND("prefix" AS ?how) }
}
ORDER BY ?ws ?how
"""


def test_parameters_give_the_same_rows_embedded_and_remote(server: OxigraphServer, tmp_path: Path) -> None:
    local = str(tmp_path / "local")
    assert cli("load", "--endpoint", server.url, str(EXAMPLE)).returncode == 0
    assert cli("load", "--store", local, str(EXAMPLE)).returncode == 0
    rq = tmp_path / "by-id.rq"
    rq.write_text(BY_ID, encoding="utf-8")
    runs = [
        [str(rq)],
        [str(rq), "--param", "ws_id=WS1 FACE RIGHT ROUGH"],
        ["workingsteps-by-tool-type", "--param", "tool_type=grooving_tool"],
        ["-e", "SELECT ?ws ?n WHERE { ?ws attr:its_id ?id FILTER(?id = ?n) }", "--param", "n=WS3 OD50 ROUGH"],
    ]
    for args in runs:
        embedded = cli("query", *args, "--store", local, "--format", "csv")
        remote = cli("query", *args, "--endpoint", server.url, "--format", "csv")
        assert embedded.returncode == 0 and remote.returncode == 0, (args, embedded.stderr, remote.stderr)
        assert embedded.stdout.count("\n") > 1, (args, embedded.stdout)  # rows, not just the header
        assert sorted(remote.stdout.splitlines()) == sorted(embedded.stdout.splitlines()), args


@pytest.mark.parametrize(("server", "ordered"), [("Virtuoso/07.20.3229 (Linux) x86_64-pc-linux-gnu", False),
                                                 ("oxigraph/0.4.11", True), (None, True)])
def test_a_store_whose_group_concat_keeps_no_order_is_named_in_the_query_warnings(server: str | None,
                                                                                   ordered: bool) -> None:
    from stepnc_graph.querying.query import concat_order_warnings

    text = 'SELECT (GROUP_CONCAT(?x; separator=", ") AS ?xs) WHERE { { SELECT ?x WHERE { ?s ?p ?x } ORDER BY ?x } }'
    with fake_endpoint(empty_store, server) as (url, _), open_remote(url) as store:
        assert store.capabilities.ordered_group_concat is ordered
        warnings = concat_order_warnings(store, text)
        if ordered:
            assert warnings == []
        else:
            assert len(warnings) == 1 and warnings[0].startswith("Virtuoso/07.20.3229") and "?xs" in warnings[0]
        assert concat_order_warnings(store, "SELECT ?x WHERE { ?s ?p ?x }") == []
    with sg.open_store(memory=True) as embedded:
        assert embedded.server is None and concat_order_warnings(embedded, text) == []


# -- a load staged in the client, written in one request (issue 30, item 4) ------------------------


def _writes(store: RemoteStore) -> list[tuple[str, str]]:
    """Record every request of ``store`` that is not a query: (method, URL's last part)."""
    seen: list[tuple[str, str]] = []
    request = store._request

    def recording(method: str, url: str, **kwargs: Any) -> Any:
        if not url.endswith("/query"):
            seen.append((method, url.rsplit("/", 1)[-1]))
        return request(method, url, **kwargs)

    store._request = recording  # type: ignore[method-assign]
    return seen


def test_a_new_program_is_written_by_one_request_and_a_replacement_by_one_update(
        server: OxigraphServer, monkeypatch: pytest.MonkeyPatch) -> None:
    """The derived layer's queries and updates run in the client; the server gets the load in one
    transactional request, with no staging graph copied or dropped (was: uploads into staging
    graphs, the derived layer's updates, one ADD swap, one DROP of the staging graphs)."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    with open_remote(server.url) as store:
        writes = _writes(store)
        [first] = sg.load(store, [EXAMPLE])
        # the probe of the load's xsd:double values (POST and DROP of a staging graph), the load
        assert writes == [("POST", "store"), ("POST", "update"), ("POST", "store")], writes
        writes.clear()
        [again] = sg.load(store, [EXAMPLE], replace=True)
        # the probe of doubles, the difference (the old version is read by a connection of its own)
        assert writes == [("POST", "store"), ("POST", "update"), ("POST", "update")], writes
        assert again.triples == first.triples and store.count(first.graph) == first.triples
        assert listed_graphs(store) == [first.graph] and not [g for g in store._all_graphs()
                                                              if _STAGING_NAME.fullmatch(g)]
    # the blank nodes the derived layer shares with the program are the program's (one document):
    # the list cells it indexes, and the values it repeats
    blank = ("SELECT (COUNT(*) AS ?n) WHERE {{ GRAPH <{g}/derived> {{ {{ ?b ?q ?x }} UNION {{ ?x ?q ?b }} "
             "FILTER(isBlank(?b)) }} }}")
    shared = blank.replace("FILTER(isBlank(?b)) }}", "FILTER(isBlank(?b)) }} FILTER EXISTS {{ GRAPH <{g}> {{ ?y ?z ?b }} }}")
    with sg.open_store(memory=True) as embedded, open_remote(server.url) as store:
        sg.load(embedded, [EXAMPLE])
        for name in embedded.all_graphs():
            assert store.count(name) == embedded.count(name), name
            assert sorted(map(str, _no_blank(embedded.quads(name)))) == sorted(map(str, _no_blank(
                store.quads(name)))), name
        for query in (blank, shared):
            [[n]] = list(store.query(query.format(g=first.graph)))
            [[here]] = list(embedded.query(query.format(g=first.graph)))
            assert int(n.value) == int(here.value) > 0, query


def _no_blank(quads: Iterator[Any]) -> list[Any]:
    import pyoxigraph as ox

    return [q for q in quads if not isinstance(q.subject, ox.BlankNode) and not isinstance(q.object, ox.BlankNode)]


def test_a_replacement_too_large_for_one_update_goes_by_staging_graphs(server: OxigraphServer,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """Oxigraph's server refuses update bodies over 128 MiB (a 100k-instance program's replacement
    is ~220 MB: it failed, "SPARQL body payloads are limited"): past a size, one N-Quads POST into
    staging graphs, one swap, then each staging graph dropped (the program's, its derived layer's,
    the load id's: three requests side by side, RemoteStore._drop_quietly)."""
    from stepnc_graph.store import remote_load

    monkeypatch.setattr(remote_load, "UPDATE_QUADS", 100)
    monkeypatch.setattr(remote_load, "replace_by_difference", lambda *args: "as if most lines changed")
    with open_remote(server.url) as store:
        [first] = sg.load(store, [EXAMPLE])
        before = {g: store.count(g) for g in store._all_graphs()}
        writes = _writes(store)
        sg.load(store, [EXAMPLE], replace=True)
        assert writes == [("POST", "store"), ("POST", "update"), ("POST", "store"), ("POST", "update"),
                          *[("POST", "update")] * 3], writes
        assert {g: store.count(g) for g in store._all_graphs()} == before
        shared = ("ASK {{ GRAPH <{g}/derived> {{ ?b ?q ?x FILTER(isBlank(?b)) }} "
                  "FILTER NOT EXISTS {{ GRAPH <{g}> {{ ?y ?z ?b }} }} }}")
        assert not store.query(shared.format(g=first.graph))
        # and a failure of the swap leaves the previous graphs and no staging graph
        monkeypatch.setattr(remote_load, "_swap", lambda store, staging: (_ for _ in ()).throw(_Died("swap")))
        with pytest.raises(_Died):
            sg.load(store, [EXAMPLE], replace=True)
        assert {g: store.count(g) for g in store._all_graphs()} == before


class _Died(Exception):
    pass


def _dying_body(monkeypatch: pytest.MonkeyPatch, then: Any = None) -> None:
    """The load's request body sends its first piece, then ``then()`` runs and the client dies:
    the connection closes with the body cut short."""
    from stepnc_graph.store import remote_load as remote

    whole = remote._NQuadsBody.__iter__

    def cut(self: Any) -> Iterator[bytes]:
        pieces = whole(self)
        yield next(pieces)
        yield next(pieces)
        if then is not None:
            then()
        raise _Died("the client died mid-request")

    monkeypatch.setattr(remote._NQuadsBody, "piece", 500)
    monkeypatch.setattr(remote._NQuadsBody, "__iter__", cut)


def test_a_client_dying_mid_request_leaves_no_new_program(server: OxigraphServer,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    _dying_body(monkeypatch)
    # no clean-up after the failure: what the server holds is what its transaction kept
    monkeypatch.setattr(RemoteStore, "_drop_quietly", lambda self, graphs: None)
    with open_remote(server.url) as store:
        with pytest.raises(_Died):
            sg.load(store, [EXAMPLE])
        assert [g for g in store._all_graphs() if not g.startswith(STAGING)] == []  # the probe's is left


def test_a_client_dying_mid_replacement_keeps_the_previous_program(server: OxigraphServer,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(remote_load, "replace_by_difference", lambda *args: "as if most lines changed")
    with open_remote(server.url) as store:
        [first] = sg.load(store, [EXAMPLE])
        before = {g: store.count(g) for g in store._all_graphs()}
        _dying_body(monkeypatch)
        with pytest.raises(_Died):
            sg.load(store, [EXAMPLE], replace=True)
        assert {g: store.count(g) for g in store._all_graphs()} == before  # its load id too
        assert listed_graphs(store) == [first.graph]


def test_a_server_killed_mid_request_keeps_no_part_of_a_new_program(server: OxigraphServer,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    _dying_body(monkeypatch, then=lambda: server.stop(signal.SIGKILL))
    monkeypatch.setenv("STEPNC_GRAPH_RETRIES", "0")
    with open_remote(server.url) as store:
        with pytest.raises((_Died, StoreError)):
            sg.load(store, [EXAMPLE])
    server.start()
    with open_remote(server.url) as store:
        assert store._all_graphs() == []


def test_a_new_program_goes_by_the_bulk_loader_where_it_is_atomic(server: OxigraphServer) -> None:
    """Oxigraph's server from 0.5 builds a bulk load's sorted index files from the whole body and
    adds them to its database in one step at the end (measured: a parse error after 1.2M quads, a
    client gone mid-body, the server killed at any point of a 1.5M-quad load: no quad kept), for a
    third of its transactional insert's CPU; the graphs of a new program go that way (was: the
    transactional POST). The kill and cut-body tests above run on this path."""
    with open_remote(server.url) as store:
        posts: list[Any] = []
        request = store._request

        counts: list[str] = []

        def recording(method: str, url: str, **kwargs: Any) -> Any:
            if url == store.endpoint.store_url and "graph" not in (kwargs.get("params") or {}):
                posts.append(kwargs.get("params"))
            if url == store.endpoint.query_url and "COUNT(*)" in dict(kwargs.get("data") or {}).get("query", ""):
                counts.append(dict(kwargs["data"])["query"])
            return request(method, url, **kwargs)

        store._request = recording  # type: ignore[method-assign]
        sg.load(store, [EXAMPLE])
        assert posts == [{"no_transaction": ""}], posts
        assert len(counts) == 1, counts  # the count read back once (was twice: 0.05-0.12 server CPU-s each at 10k)
        with sg.open_store(memory=True) as embedded:
            sg.load(embedded, [EXAMPLE])
            for name in embedded.all_graphs():
                assert store.count(name) == embedded.count(name) > 0, name


@pytest.mark.parametrize(("header", "bulk"), [("Oxigraph/0.5.13", True), ("Oxigraph/0.5.0", True),
                                              ("oxigraph/1.2.0", True), ("Oxigraph/0.4.11", False),
                                              ("Oxigraph/0.3.22", False), ("Virtuoso/07.20.3240", False),
                                              (None, False)])
def test_only_servers_whose_bulk_load_is_atomic_get_one(header: str | None, bulk: bool) -> None:
    """Oxigraph 0.4's bulk loader added its files batch by batch (a failure kept the batches before)."""
    from stepnc_graph.store.remote import atomic_bulk_post

    assert atomic_bulk_post(header) is bulk


def test_the_body_is_every_graph_renamed_with_shared_blank_nodes_one_node_and_no_thread_left() -> None:
    """The N-Quads body is Oxigraph's dump of each staged graph (made on a thread while it is
    sent): every quad under its new name, a blank node two graphs share one label, pieces that end
    at a line's end; a reader that stops early (a failed request) leaves no dump thread behind."""
    import pyoxigraph as ox

    from stepnc_graph.store import GraphStore

    with GraphStore(None) as local:
        shared = ox.BlankNode()
        staged = {f"urn:staged:{i}": f"https://example.org/g{i}" for i in range(2)}
        quads = [ox.Quad(ox.NamedNode(f"https://example.org/s{n}"), ox.NamedNode("https://example.org/p"),
                         ox.Literal(f"value {n} .\n with a line break"), ox.NamedNode(g))
                 for n in range(3000) for g in staged]
        quads += [ox.Quad(ox.NamedNode("https://example.org/list"), ox.NamedNode("https://example.org/p"), shared,
                          ox.NamedNode(g)) for g in staged]
        local.oxigraph.extend(quads)
        body = remote_load._NQuadsBody(local, staged)
        body.piece = 4096
        pieces = list(body)
        assert len(pieces) > 10 and all(piece.endswith(b" .\n") for piece in pieces)
        got = list(ox.parse(b"".join(pieces), ox.RdfFormat.N_QUADS))
        assert sorted(str(q) for q in got if not isinstance(q.object, ox.BlankNode)) == sorted(
            str(ox.Quad(q.subject, q.predicate, q.object, ox.NamedNode(staged[q.graph_name.value])))
            for q in quads if not isinstance(q.object, ox.BlankNode))
        assert len({q.object for q in got if isinstance(q.object, ox.BlankNode)}) == 1
        assert sorted(q.graph_name.value for q in got if isinstance(q.object, ox.BlankNode)) == sorted(staged.values())
        again = list(body)  # iterable again from the start: a request sent again sends it whole
        assert b"".join(again) == b"".join(pieces)
        before = threading.active_count()
        reader = iter(body)
        next(reader)
        reader.close()  # type: ignore[attr-defined]
        assert threading.active_count() == before


def _keeping_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    """The server answers every write of a load (the N-Quads POST and the replacement's update
    that streams the program) and keeps none of it."""
    request = RemoteStore._request

    def answer_only(self: RemoteStore, method: str, url: str, **kw: Any) -> Any:
        body = kw.get("data")
        if url == self.endpoint.update_url and body is not None and not isinstance(body, (str, bytes)):
            sum(len(piece) for piece in body)
            return None
        return request(self, method, url, **kw)

    monkeypatch.setattr(RemoteStore, "_post_dataset", lambda self, body: sum(len(piece) for piece in body))
    monkeypatch.setattr(RemoteStore, "_request", answer_only)


def test_a_server_that_answers_the_load_but_keeps_nothing_is_an_error(server: OxigraphServer,
                                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    _keeping_nothing(monkeypatch)
    with open_remote(server.url) as store:
        with pytest.raises(StoreError, match="it was not loaded"):
            sg.load(store, [EXAMPLE])
        assert store._all_graphs() == []


def test_two_loads_creating_the_same_graph_at_once_leave_one_of_them_whole(server: OxigraphServer,
                                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """Both clients find the graph missing, so both POST into it (a POST adds to a graph): the
    second then holds two copies of the program's blank-node structure, a mix nobody loaded.
    The load that finds more triples than it wrote replaces the graph by itself, atomically."""
    with open_remote(server.url) as store:
        [first] = sg.load(store, [EXAMPLE])
        alone = {g: store.count(g) for g in store._all_graphs()}
        monkeypatch.setattr(RemoteStore, "has_graph", lambda self, graph: False)  # as the other client saw it
        [second] = sg.load(store, [EXAMPLE])
        assert second.graph == first.graph
        assert {g: store.count(g) for g in store._all_graphs()} == alone
        instances = store.query(f"SELECT (COUNT(?s) AS ?n) WHERE {{ GRAPH <{first.graph}> {{ ?s "
                                "<https://w3id.org/stepnc-graph/p21#id> ?id } }")
        assert int(next(iter(instances))[0].value) == first.instances


def test_a_server_that_rounds_doubles_is_found_by_the_probe_and_left_unchanged(
        server: OxigraphServer, monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """As Virtuoso 7 does (six significant digits): the probe graph reads back other values."""
    post = RemoteStore._post_graph

    def rounding(self: RemoteStore, graph: str, body: bytes, media_type: str = "application/n-triples") -> None:
        rounded = re.sub(rb'"([-+0-9.eE]+)"\^\^', lambda m: b'"%s"^^' % (b"%.6g" % float(m.group(1))), body)
        post(self, graph, rounded, media_type)

    monkeypatch.setattr(RemoteStore, "_post_graph", rounding)
    with open_remote(server.url) as store:
        [first] = sg.load(store, [EXAMPLE])
        before = {g: store.count(g) for g in store._all_graphs()}
        text = EXAMPLE.read_text().replace("(0.,0.,0.)", "(0.12345678901,0.,0.)", 1)
        assert text != EXAMPLE.read_text()
        path = tmp_path / "long-double.stp"
        path.write_text(text)
        with pytest.raises(StoreError, match="does not give back the xsd:double values"):
            sg.load(store, [path])
        assert {g: store.count(g) for g in store._all_graphs()} == before and first.graph in before


def test_a_library_query_a_store_answers_wrongly_is_named_with_its_answer() -> None:
    from stepnc_graph.querying.query import known_wrong_answers
    from stepnc_graph.store.behaviour import BEHAVIOURS

    [name] = {q for b in BEHAVIOURS for q in b.queries}
    with fake_endpoint(empty_store, "Virtuoso/07.20.3229 (Linux)") as (url, _), open_remote(url) as store:
        [said] = known_wrong_answers(store, name)
        assert said.startswith("Virtuoso/07.20.3229") and "drops rows" in said
        assert known_wrong_answers(store, "tool-changes") == []
    with fake_endpoint(empty_store, "Oxigraph/0.5.2") as (url, _), open_remote(url) as store:
        assert known_wrong_answers(store, name) == []


@pytest.mark.parametrize("graph", [None, "program"])
def test_a_library_query_a_store_drops_rows_of_is_answered_from_a_copy(
        server: OxigraphServer, monkeypatch: pytest.MonkeyPatch, graph: str | None) -> None:
    """A store known to drop rows of a library query (Virtuoso's operations-per-feature, in
    store/behaviour.py) is not asked it: the embedded engine answers it over a copy of the graphs
    it reads, with the embedded store's rows and a warning saying so. The live Oxigraph server
    stands in for such a store here, its entry in the table made to say so."""
    import stepnc_graph.querying.query as querying
    from stepnc_graph.store.behaviour import Behaviour

    name = "operations-per-feature"
    defect = Behaviour(re.compile("Oxigraph"), "drops rows of this query (said by the test)", queries=frozenset({name}))
    monkeypatch.setattr(querying, "wrong_answers", lambda srv, q: [defect] if q == name and srv else [])
    with sg.open_store(memory=True) as embedded, open_remote(server.url) as store:
        [here_loaded] = sg.load(embedded, [EXAMPLE])
        [r] = sg.load(store, [EXAMPLE])
        asked: list[str] = []
        query = store.query
        monkeypatch.setattr(store, "query", lambda text, **kw: asked.append(text) or query(text, **kw))
        got = sg.query(store, name, graph=r.graph if graph else None)
        want = sg.query(embedded, name, graph=here_loaded.graph if graph else None)
        assert got.rows == want.rows and len(want.rows) > 3
        [said] = [w for w in got.warnings if "own engine" in w]
        assert said.startswith(f"{store.server} drops rows of this query") and "copy of" in said
        assert not [text for text in asked if "operations planned" in text or "?operations" in text]
        assert sg.query(store, "tool-changes").rows == sg.query(embedded, "tool-changes").rows
        assert [text for text in asked if "?changes" in text or "tool" in text.lower()]  # asked the store itself


def test_a_difference_reaches_old_blank_nodes_by_their_paths_and_names_new_ones_in_the_template() -> None:
    """The update of a replacement by difference, run on a store holding the old version: a list
    cell's value changed (reached from its owner down the list), a list added (new nodes, one of
    them shared with another graph), one removed; a member of a SET of lists has no path."""
    import pyoxigraph as ox

    from stepnc_graph.store.remote_difference import LOAD_ID, Paths, token_graph, token_line

    g, d = "http://example.org/g", "http://example.org/g/derived"
    rdf = "<http://www.w3.org/1999/02/22-rdf-syntax-ns#"
    old = [f'<{g}#1> <{g}#p> _:a .\n', f'_:a {rdf}first> "1" .\n', f'_:a {rdf}rest> _:b .\n',
           f'_:b {rdf}first> "2" .\n', f'_:b {rdf}rest> {rdf}nil> .\n', f'<{g}#1> <{g}#p> <{g}#named> .\n',
           f'<{g}#2> <{g}#p> _:c .\n', f'_:c {rdf}first> "3" .\n', f'_:c {rdf}rest> {rdf}nil> .\n',
           f'<{g}#3> <{g}#set> _:s1 .\n', f'<{g}#3> <{g}#set> _:s2 .\n', f'_:s1 {rdf}first> "4" .\n',
           f'_:s2 {rdf}first> "5" .\n']
    derived = ['_:b <http://example.org/index> "2" .\n']
    store = ox.Store()
    for name, lines in ((g, old), (d, derived), (token_graph(g), [token_line(g, "old")])):
        store.load("".join(lines).encode(), ox.RdfFormat.N_TRIPLES, to_graph=ox.NamedNode(name))
    served = {name: [line.encode() for line in ox.serialize(
        [q.triple for q in store.quads_for_pattern(None, None, None, ox.NamedNode(name))],
        format=ox.RdfFormat.N_TRIPLES).decode().splitlines(keepends=True)] for name in (g, d)}
    first = ox.NamedNode("http://www.w3.org/1999/02/22-rdf-syntax-ns#first")
    label = {q.object.value: q.subject for q in store.quads_for_pattern(None, first, None, None)}
    b, c = label["2"].value.encode(), label["3"].value.encode()
    every = {lab for lines in served.values() for line in lines for lab in re.findall(rb"_:(\S+)", line)}
    paths = Paths(served[g], every)
    gone = [line for line in served[g] if line.startswith(b"_:" + b + b" ") and b'"2"' in line]
    gone += [line for line in served[g] if b"#2>" in line or line.startswith(b"_:" + c + b" ")]
    came = [b"_:" + b + f' {rdf}first> "20" .\n'.encode(), f'<{g}#4> <{g}#p> _:new .\n'.encode(),
            f'_:new {rdf}first> "6" .\n'.encode(), f'_:new {rdf}rest> {rdf}nil> .\n'.encode()]
    update = paths.update(g, {g: (gone, came), d: ([], [b'_:new <http://example.org/index> "1" .\n']),
                              token_graph(g): ([token_line(g, "old").encode()], [token_line(g, "new").encode()])},
                          "old")
    assert update is not None
    store.update(update)
    assert [q.object.value for q in store.quads_for_pattern(None, ox.NamedNode(LOAD_ID), None, None)] == ["new"]
    values = {q.object.value for q in store.quads_for_pattern(None, None, None, ox.NamedNode(g))
              if isinstance(q.object, ox.Literal)}
    assert values == {"1", "20", "4", "5", "6"}  # "2" changed, "3" gone with its list, "6" came
    [new_cell] = [q.subject for q in store.quads_for_pattern(None, None, ox.Literal("6"), ox.NamedNode(g))]
    assert ox.Quad(new_cell, ox.NamedNode("http://example.org/index"), ox.Literal("1"), ox.NamedNode(d)) in store
    held = len(old) + len(derived) + 1  # and the token
    assert len(store) == held - 3 + 3 + 1  # one line changed, a list of 3 out, one of 3 in, one derived line in
    store.update(update)  # again: the load id is no longer "old", so nothing changes
    assert len(store) == held - 3 + 3 + 1 and "20" in {q.object.value for q in store}
    # a SET member's cell has no path of its own: no update
    s1 = next(q.object for q in store.quads_for_pattern(ox.NamedNode(f"{g}#3"), None, None, ox.NamedNode(g)))
    line = f'{s1} {rdf}first> "7" .\n'.encode()
    assert Paths(served[g], every).update(g, {g: ([], [line])}, "new") is None


def test_an_upload_interrupted_while_it_finishes_sends_nothing_more() -> None:
    """Ctrl-C while a load staged in the store waits for its last batches: the batches still
    waiting are not sent, and the one under way has ended when the interrupt reaches the caller,
    which then drops the staging graphs (a POST after that drop left them behind)."""
    import threading

    from stepnc_graph.store.remote_load import _Uploader

    sent: list[str] = []

    class Slow:
        def _post_graph(self, graph: str, body: bytes) -> None:
            time.sleep(0.3)
            sent.append(graph)

    uploader = _Uploader(Slow())  # type: ignore[arg-type]
    timer = threading.Timer(0.4, os.kill, (os.getpid(), signal.SIGINT))  # Ctrl-C
    with pytest.raises(KeyboardInterrupt):
        with uploader:
            for name in "abc":
                uploader.send(name, b"")
            timer.start()  # the interrupt comes while the block's end waits for the batches
    timer.join()
    then = list(sent)
    time.sleep(0.8)  # what the batches left would take
    assert sent == then and len(sent) < 3, (then, sent)
