"""The forwarding layer of ``serve`` (:mod:`.serve`): an HTTP server in front of Oxigraph's that checks
the Host header, refuses writes unless ``--writable`` (403), SPARQL that would reach the network,
bodies over the request limit (413) and results over the size limit (507), and forwards the rest
to the current Oxigraph server, rebuilding a SPARQL operation so that the text checked is the
text sent.
"""

from __future__ import annotations

import http.client
import http.server
import re
import socket
import sys
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qsl, urlencode, urlsplit

import pyoxigraph as ox

from stepnc_graph.core.outbound import OutboundRefused, outbound_keyword, refuse_outbound

if TYPE_CHECKING:
    from stepnc_graph.server.serve import Endpoint


LOOPBACK = ("127.0.0.1", "localhost", "::1")
_WRITES = {"PUT", "DELETE", "PATCH"}
_CANCELLED = b"The SPARQL operation has been cancelled"
_HOP_BY_HOP = {"connection", "keep-alive", "transfer-encoding", "te", "trailer", "upgrade", "proxy-authorization",
               "proxy-authenticate", "content-length"}


def host_names(host: str, extra: tuple[str, ...]) -> frozenset[str]:
    """The names a request's Host may give: loopback names, the address listened on, the names
    asked for, and, listening on every interface, this machine's own names."""
    names = {"localhost", *LOOPBACK, host.lower(), *(e.lower().rstrip(".") for e in extra)}
    if host in ("0.0.0.0", "::", ""):
        names |= {socket.gethostname().lower(), socket.getfqdn().lower()}
    return frozenset(n for n in names if n)


class Server(http.server.ThreadingHTTPServer):
    """The forwarding layer's HTTP server: IPv4 or IPv6 as the address asks; a client that goes
    away mid-answer is no error worth a traceback."""

    daemon_threads = True

    def __init__(self, address: tuple[str, int], handler: type[http.server.BaseHTTPRequestHandler]) -> None:
        infos = socket.getaddrinfo(address[0], address[1], type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
        self.address_family = infos[0][0] if infos else socket.AF_INET
        super().__init__(address, handler)

    def handle_error(self, request: Any, client_address: Any) -> None:
        if isinstance(sys.exc_info()[1], (ConnectionError, TimeoutError)):
            return  # the client closed the connection (BrokenPipe, reset) or stopped sending
        super().handle_error(request, client_address)


class _Refused(Exception):
    """A request answered by the forwarding layer itself, with ``status`` and ``text``; ``close``
    when its body was not read (the connection cannot carry another request)."""

    def __init__(self, status: int, text: str, close: bool = False) -> None:
        super().__init__(text)
        self.status, self.text, self.close = status, text, close


@dataclass(frozen=True)
class _Request:
    """What goes to Oxigraph's server: a SPARQL operation rebuilt by the forwarding layer (the text
    that was checked is the text sent), or another request passed on as it came."""

    method: str
    path: str
    body: bytes | None
    headers: dict[str, str]
    writes: bool


class Forward(http.server.BaseHTTPRequestHandler):
    """Forwards a request to the current Oxigraph server; refuses writes and oversized results."""

    endpoint: Endpoint
    protocol_version = "HTTP/1.1"

    def log_message(self, *args: Any) -> None:  # the endpoint's own access log is not wanted on the terminal
        pass

    def do_GET(self) -> None:  # noqa: N802 -- http.server's API
        self._forward()

    def do_HEAD(self) -> None:  # noqa: N802
        self._forward()

    def do_POST(self) -> None:  # noqa: N802
        self._forward()

    def do_PUT(self) -> None:  # noqa: N802
        self._forward()

    def do_DELETE(self) -> None:  # noqa: N802
        self._forward()

    def do_OPTIONS(self) -> None:  # noqa: N802
        self._forward()

    def _answer(self, status: int, text: str, close: bool = False) -> None:
        body = (text + "\n").encode()
        self.send_response(status)
        self.send_header("Content-Type", "text/plain; charset=utf-8")
        self.send_header("Content-Length", str(len(body)))
        if close:
            self.send_header("Connection", "close")
            self.close_connection = True
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _forward(self) -> None:
        try:
            self._check_origin()
            request = _prepare(self.command, self.path, self.headers, self._body(), self.endpoint)
            self._send(request)
        except _Refused as refused:
            self._answer(refused.status, refused.text, refused.close)

    # -- the request ---------------------------------------------------------------------

    def _check_origin(self) -> None:
        """Refuse a request that names another host (DNS rebinding: a web page's own name made to
        point at this machine) or that a browser sends from another site's page."""
        host = self.headers.get("Host")
        if host is None:
            if self.request_version == "HTTP/1.1":
                raise _Refused(400, "an HTTP/1.1 request needs a Host header", close=True)
        elif not self.endpoint.host_allowed(host):
            raise _Refused(421, f"this endpoint does not answer to the host name {host[:100]!r}: it answers to "
                                f"{', '.join(sorted(self.endpoint.allowed_hosts))} and IP addresses (serve "
                                "--allow-host NAME adds a name, e.g. a reverse proxy's)", close=True)
        origin = self.headers.get("Origin")
        if origin is not None and origin != "null" and not self.endpoint.host_allowed(urlsplit(origin).netloc):
            raise _Refused(403, f"requests from web pages of {origin[:100]} are refused", close=True)
        if origin == "null" or self.headers.get("Sec-Fetch-Site", "") == "cross-site":
            raise _Refused(403, "requests from another site's web page are refused", close=True)

    def _body(self) -> bytes | None:
        """The request body, read whole: at most ``max_request_bytes``, with a valid Content-Length."""
        if self.headers.get("Transfer-Encoding") is not None:
            raise _Refused(411, "send the request body with a Content-Length (chunked transfer coding is not "
                                "accepted)", close=True)
        values = {v.strip() for v in self.headers.get_all("Content-Length") or []}
        if not values:
            return None
        text = values.pop()
        if values or not re.fullmatch(r"[0-9]{1,20}", text):
            raise _Refused(400, "the Content-Length header must be one whole number of bytes", close=True)
        length = int(text)
        limit = self.endpoint.max_request_bytes
        if length > limit:
            raise _Refused(413, f"the request body ({length} bytes) is larger than {limit} bytes (serve "
                                "--max-request-bytes sets the limit)", close=True)
        body = self.rfile.read(length)
        if len(body) < length:
            raise _Refused(400, f"the request body ended after {len(body)} of {length} bytes", close=True)
        return body

    # -- the answer ----------------------------------------------------------------------

    def _public(self) -> str:
        """This endpoint's address as the client named it (its Host, already checked), else its own."""
        host = self.headers.get("Host", "")
        return f"http://{host}" if host and self.endpoint.host_allowed(host) else self.endpoint.url

    def _send(self, request: _Request) -> None:
        endpoint = self.endpoint
        if request.writes and not endpoint.writable:
            raise _Refused(403, "this endpoint is read-only (stepnc-graph serve --writable allows updates)")
        backend = endpoint.backend
        if backend is None:
            raise _Refused(503, "the endpoint is stopping")
        started = time.monotonic()
        upstream = http.client.HTTPConnection("127.0.0.1", backend.port, timeout=endpoint.timeout + 5)
        try:
            upstream.request(request.method, request.path, body=request.body, headers=request.headers)
            sock = upstream.sock
            response = upstream.getresponse()
            data = _read_until(response, sock, endpoint.max_bytes + 1, started + endpoint.timeout + 5)
        except TimeoutError:
            data = None
        except (OSError, http.client.HTTPException) as e:
            raise _Refused(502, f"the Oxigraph server did not answer: {e}") from None
        finally:
            upstream.close()
        if data is None or time.monotonic() - started >= endpoint.timeout or data.rstrip().endswith(_CANCELLED):
            # Oxigraph cancels a query at its timeout after it sent "200 OK" and part of the
            # result: a client must not take that for an answer
            raise _Refused(503, f"the query took longer than {endpoint.timeout} s and was cancelled (serve "
                                "--timeout sets the limit)")
        if len(data) > endpoint.max_bytes:
            raise _Refused(507, f"the result is larger than {endpoint.max_bytes} bytes: ask for less (LIMIT, a "
                                "narrower graph), or start serve with a larger --max-bytes")
        media_type = (response.getheader("Content-Type") or "").split(";")[0].strip().lower()
        if response.status == 200 and request.method in ("GET", "HEAD") and _describes_service(request.path):
            # the service description names the back end's own address: clients get this one's
            data = data.replace(f"http://127.0.0.1:{backend.port}/".encode(), f"{self._public()}/".encode())
        broken = _incomplete(data, media_type) if response.status == 200 and self.command != "HEAD" else None
        if broken is not None:
            raise _Refused(500, f"the Oxigraph server failed while writing the result: {broken}")
        self.send_response(response.status, response.reason)
        for key, value in response.getheaders():
            if key.lower() not in _HOP_BY_HOP:
                self.send_header(key, value)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(data)


def _describes_service(target: str) -> bool:
    """Whether a GET of ``target`` asks for the service description (a SPARQL path, no operation)."""
    path, _, query_string = target.partition("?")
    return path in _SPARQL_PATHS and not any(k in ("query", "update") for k, _ in parse_qsl(query_string))


#: paths where Oxigraph's server runs SPARQL operations, and what each runs from a direct body
_SPARQL_PATHS = ("/query", "/update", "/sparql")
_FORM = "application/x-www-form-urlencoded"
_DIRECT = {"application/sparql-query": "query", "application/sparql-update": "update"}
#: request headers not passed to Oxigraph for a rebuilt SPARQL operation (it gets its own body)
_REBUILT = _HOP_BY_HOP | {"host", "content-type", "content-encoding"}


def _prepare(method: str, target: str, headers: Any, body: bytes | None, endpoint: Endpoint) -> _Request:
    """The request to send Oxigraph's server for ``method`` and ``target`` (path and query string).

    A SPARQL operation -- the ``query`` or ``update`` parameter of the URL or of a form body, or
    a direct body -- is taken out of the request whichever way it came, checked
    (:func:`~stepnc_graph.core.outbound.refuse_outbound`: ``SERVICE`` and ``LOAD`` are refused unless
    ``--allow-service``), and sent on as a form of its own: Oxigraph runs the text that was
    checked, never one it reads differently from the request (a second parameter, another
    spelling of the media type)."""
    path, _, query_string = target.partition("?")
    params = _form(query_string.encode("latin-1", "replace"), "the URL's query string")
    media_type = (headers.get("Content-Type") or "").split(";")[0].strip().lower()
    sparql_path = path in _SPARQL_PATHS
    operations = [(k, v) for k, v in params if k in ("query", "update")]
    if method == "POST" and sparql_path:
        if media_type == _FORM:
            form = _form(body or b"", "the form body")
            params += form
            operations += [(k, v) for k, v in form if k in ("query", "update")]
        elif media_type in _DIRECT:
            operations.append((_DIRECT[media_type], _text(body or b"", "the request body")))
        else:
            raise _Refused(415, f"a SPARQL request's body must be {_FORM}, application/sparql-query or "
                                f"application/sparql-update, not {media_type or 'untyped'}")
    if operations and not sparql_path:
        raise _Refused(400, f"a query or update is sent to {', '.join(_SPARQL_PATHS)}")
    if len(operations) > 1:
        raise _Refused(400, "give one query or one update per request")
    if operations:
        kind, text = operations[0]
        if kind == "update" and _is_query(text):
            # some clients guess the operation from the words of its text (SPARQLWrapper takes
            # "Loading" in a comment for LOAD) and send a query as an update: the text decides
            kind = "query"
        try:
            refuse_outbound(text, update=kind == "update", allow=endpoint.allow_service)
        except OutboundRefused as exc:
            raise _Refused(403, f"{exc} (a serve option)") from None
        if method not in ("GET", "HEAD", "POST"):
            raise _Refused(405, f"a SPARQL {kind} is sent with GET or POST")
        rest = [(k, v) for k, v in params if k not in ("query", "update")]
        forwarded = {k: v for k, v in headers.items() if k.lower() not in _REBUILT}
        forwarded["Content-Type"] = _FORM
        return _Request("POST", f"/{kind}", urlencode([(kind, text), *rest]).encode(), forwarded,
                        writes=kind == "update")
    if sparql_path and method not in ("GET", "HEAD", "OPTIONS"):
        raise _Refused(400, "no query or update in the request")
    forwarded = {k: v for k, v in headers.items() if k.lower() not in _HOP_BY_HOP and k.lower() != "host"}
    writes = method in _WRITES or (method == "POST" and not sparql_path)
    return _Request(method, target, body, forwarded, writes)


def _is_query(text: str) -> bool:
    """Whether ``text`` parses as a SPARQL query (on an empty store, where it finds nothing; never
    one that may send a request: SERVICE)."""
    if outbound_keyword(text) is not None:
        return False
    try:
        ox.Store().query(text)
    except (SyntaxError, RuntimeError, ValueError):
        return False
    return True


def _text(data: bytes, what: str) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise _Refused(400, f"{what} is not UTF-8") from None


def _form(data: bytes, what: str) -> list[tuple[str, str]]:
    """``application/x-www-form-urlencoded`` pairs, percent-escapes read as UTF-8 (400 otherwise)."""
    try:
        return parse_qsl(data.decode("ascii"), keep_blank_values=True, strict_parsing=False, errors="strict",
                         max_num_fields=1000)
    except (UnicodeError, ValueError):
        raise _Refused(400, f"{what} is not a valid form (ASCII, percent-escaped UTF-8, at most 1000 fields)") \
            from None


def _read_until(response: http.client.HTTPResponse, sock: socket.socket | None, limit: int,
                deadline: float) -> bytes:
    """Up to ``limit`` bytes of ``response`` (read from ``sock``); TimeoutError once ``deadline``
    (monotonic) has passed, however slowly the bytes come."""
    parts: list[bytes] = []
    size = 0
    while size < limit:
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            raise TimeoutError
        if sock is not None:
            sock.settimeout(remaining)
        part = response.read1(min(1 << 20, limit - size))
        if not part:
            break
        parts.append(part)
        size += len(part)
    return b"".join(parts)


#: SPARQL results formats by media type
_RESULTS = {"application/sparql-results+json": ox.QueryResultsFormat.JSON,
            "application/sparql-results+xml": ox.QueryResultsFormat.XML,
            "text/tab-separated-values": ox.QueryResultsFormat.TSV, "text/csv": ox.QueryResultsFormat.CSV}


def _incomplete(data: bytes, media_type: str) -> str | None:
    """Why ``data`` is not a complete document of ``media_type`` (None when it is, or when the type
    is not one Oxigraph writes results in).

    Oxigraph's server sends "200 OK" before a result is evaluated; an error while it writes one
    (a failed SERVICE call, say) ends the body with the error's text. Parsing the whole document
    finds that; a CSV row can hold any text (and CSV results cannot be parsed back), so a CSV
    result must end as each of its rows does."""
    try:
        if media_type == "text/csv":  # lossy: no parser reads it back
            if data and not data.endswith(b"\r\n"):
                raise SyntaxError("the last row is cut short")
            return None
        if media_type in _RESULTS:
            parsed = ox.parse_query_results(data, format=_RESULTS[media_type])
            if isinstance(parsed, ox.QuerySolutions):
                parsed.serialize(format=ox.QueryResultsFormat.TSV)  # reads every row, in Rust
            return None
        rdf = ox.RdfFormat.from_media_type(media_type)
        if rdf is not None:  # relative IRIs (the service description's <>) are the client's to resolve
            for _ in ox.parse(data, rdf, base_iri="http://localhost/"):
                pass
        return None
    except (SyntaxError, ValueError) as exc:
        tail = data[-300:].decode("utf-8", "replace").strip().splitlines()
        return f"{tail[-1] if tail else ''} ({exc})"


def is_loopback(host: str) -> bool:
    return host in LOOPBACK
