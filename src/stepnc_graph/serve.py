"""``stepnc-graph serve``: the store as a SPARQL 1.1 Protocol endpoint, by Oxigraph's own server.

The SPARQL work is Oxigraph's server (``oxigraph serve-read-only``, from the
``oxigraph`` PyPI package) running over the store's published generation: the
SPARQL 1.1 Protocol for queries, the Graph Store Protocol for reading graphs,
its query timeout. In front of it sits a thin forwarding layer, because
Oxigraph's server has no result-size limit and a store's published state moves
on with every load:

* it refuses every request that would write (``/update``, Graph Store ``PUT``,
  ``POST``, ``DELETE``) with 403 unless ``--writable`` was asked for;
* it answers 507 instead of a result larger than ``max_bytes``;
* it follows new generations: when a load publishes one, a new Oxigraph server
  starts on it, requests go there, and the old one stops -- no downtime, and the
  generation a server reads is locked (readers' lock) so no writer deletes it.

It binds to 127.0.0.1 unless another host is asked for. ``--writable`` serves the
writer's database instead (holding the writer's lock, so loads wait or fail):
Oxigraph runs every update in a transaction, so the database stays consistent;
the changes are published as a generation when ``serve`` stops, and a writer
that finds a ``serve`` killed mid-way publishes what it had instead of
discarding it.
"""

from __future__ import annotations

import http.client
import http.server
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from stepnc_graph.store import GraphStore, StoreError, _Locks

LOOPBACK = ("127.0.0.1", "localhost", "::1")
#: result bytes above which a response is refused (a browser or script asking for a whole store)
DEFAULT_MAX_BYTES = 100 << 20
DEFAULT_TIMEOUT = 60
_WRITES = {"PUT", "DELETE", "PATCH"}
_CANCELLED = b"The SPARQL operation has been cancelled"
_HOP_BY_HOP = {"connection", "keep-alive", "transfer-encoding", "te", "trailer", "upgrade", "proxy-authorization",
               "proxy-authenticate", "content-length"}


class ServeError(StoreError):
    """The endpoint cannot be started as asked."""


def oxigraph_binary() -> str:
    """The ``oxigraph`` server program (``pip install 'stepnc-graph[serve]'`` installs it)."""
    found = shutil.which("oxigraph") or str(Path(sys.executable).parent / "oxigraph")
    if not Path(found).exists():
        raise ServeError("the Oxigraph server is not installed: pip install 'stepnc-graph[serve]' (the oxigraph "
                         "package)")
    return found


def _die_with_parent() -> None:
    """In the Oxigraph child: be stopped when serve dies, even by kill -9 (Linux), so no server
    is left holding the store."""
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6", use_errno=True)
        libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass  # not Linux: a killed serve may leave its Oxigraph server running


def free_port() -> int:
    """A free TCP port on the loopback interface."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class _Backend:
    """One Oxigraph server over one database directory, on an internal loopback port."""

    process: subprocess.Popen[bytes]
    port: int
    location: Path
    lock_fd: int | None

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout=20)
        _Locks.release(self.lock_fd)
        self.lock_fd = None


class Endpoint:
    """The SPARQL endpoint over a store directory (see the module docstring)."""

    def __init__(self, store: Path, host: str = "127.0.0.1", port: int = 7878, *, writable: bool = False,
                 timeout: int = DEFAULT_TIMEOUT, max_bytes: int = DEFAULT_MAX_BYTES, union_default_graph: bool = False,
                 follow: bool = True, poll: float = 1.0) -> None:
        self.store = store
        self.host, self.port = host, port
        self.writable, self.timeout, self.max_bytes = writable, timeout, max_bytes
        self.union_default_graph, self.follow, self.poll = union_default_graph, follow, poll
        self.binary = oxigraph_binary()
        self.backend: _Backend | None = None
        self._writer: GraphStore | None = None
        self._httpd: http.server.ThreadingHTTPServer | None = None
        self._stopping = threading.Event()
        self._swap = threading.Lock()  # the follower's switch and stop() do not interleave

    # -- backends ---------------------------------------------------------------------

    def _start_backend(self, location: Path, lock_fd: int | None) -> _Backend:
        port = free_port()
        command = [self.binary, "serve" if self.writable else "serve-read-only", "--location", str(location),
                   "--bind", f"127.0.0.1:{port}", "--timeout-s", str(self.timeout)]
        if self.union_default_graph:
            command.append("--union-default-graph")
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                   preexec_fn=_die_with_parent)
        backend = _Backend(process, port, location, lock_fd)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            if process.poll() is not None:
                message = process.stderr.read().decode(errors="replace").strip() if process.stderr else ""
                backend.stop()
                raise ServeError(f"the Oxigraph server stopped at once: {message[-300:]}")
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                    return backend
            except OSError:
                time.sleep(0.05)
        backend.stop()
        raise ServeError("the Oxigraph server did not start within 30 s")

    def _pinned_generation(self) -> tuple[str, int]:
        """The published generation, with a readers' lock on it (so no writer deletes it)."""
        for _ in range(100):
            current = (self.store / "CURRENT").read_text().strip() if (self.store / "CURRENT").exists() else ""
            if not current:
                raise ServeError(f"no published store in {self.store}")
            fd = _Locks.try_lock(self.store / f"{current}.lock", shared=True)
            if fd is not None and (self.store / current).is_dir():
                return current, fd
            _Locks.release(fd)
            time.sleep(0.01)
        raise ServeError(f"cannot get a consistent view of {self.store}")

    def _read_only_backend(self) -> _Backend:
        with GraphStore(self.store, readonly=True, create=False):  # checks the store (and migrates format 1)
            pass
        generation, fd = self._pinned_generation()
        try:
            return self._start_backend(self.store / generation, fd)
        except BaseException:
            _Locks.release(fd)
            raise

    def _follow(self) -> None:
        """Switch to each newly published generation without dropping a request."""
        while not self._stopping.wait(self.poll):
            backend = self.backend
            if backend is None:
                continue
            current = (self.store / "CURRENT").read_text().strip() if (self.store / "CURRENT").exists() else ""
            if current and backend.location.name != current:
                try:
                    fresh = self._read_only_backend()
                except (ServeError, StoreError, OSError):
                    continue  # try again at the next poll
                with self._swap:
                    if self._stopping.is_set():  # stop() ran meanwhile: this one is not wanted
                        fresh.stop()
                        return
                    self.backend = fresh
                time.sleep(0.5)  # requests already sent to the old server finish there
                backend.stop()

    # -- running -----------------------------------------------------------------------

    def start(self) -> None:
        """Start Oxigraph's server and the forwarding layer; returns once both listen."""
        if self.writable:
            self._writer = GraphStore(self.store, create=False)
            location = self._writer.serving()
            self.backend = self._start_backend(location, None)
        else:
            self.backend = self._read_only_backend()
        handler = type("Handler", (_Forward,), {"endpoint": self})
        try:
            self._httpd = http.server.ThreadingHTTPServer((self.host, self.port), handler)
        except OSError as e:
            self.stop()
            raise ServeError(f"cannot listen on {self.host}:{self.port}: {e.strerror or e}") from None
        self._httpd.daemon_threads = True
        self.port = int(self._httpd.server_address[1])
        if self.follow and not self.writable:
            threading.Thread(target=self._follow, daemon=True).start()

    def serve_forever(self) -> None:
        """Serve until SIGINT or SIGTERM, then stop cleanly."""
        assert self._httpd is not None

        def stop(*_: object) -> None:
            threading.Thread(target=self._httpd.shutdown, daemon=True).start()  # type: ignore[union-attr]

        signal.signal(signal.SIGINT, stop)
        signal.signal(signal.SIGTERM, stop)
        try:
            self._httpd.serve_forever(poll_interval=0.2)
        finally:
            self.stop()

    def stop(self) -> None:
        """Stop the servers and release the store (publishing a writable server's changes)."""
        self._stopping.set()
        if self._httpd is not None:
            self._httpd.server_close()
            self._httpd = None
        with self._swap:
            if self.backend is not None:
                self.backend.stop()
                self.backend = None
        if self._writer is not None:
            self._writer.served()
            self._writer.close()
            self._writer = None

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}"


class _Forward(http.server.BaseHTTPRequestHandler):
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

    def _writes(self) -> bool:
        path = self.path.split("?", 1)[0].rstrip("/")
        if self.command in _WRITES:
            return True
        return self.command == "POST" and (path.endswith("/update") or path.endswith("/store"))

    def _answer(self, status: int, text: str) -> None:
        body = (text + "\n").encode()
        self.send_response(status)
        self.send_header("Content-Type", "text/plain; charset=utf-8")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _forward(self) -> None:
        endpoint = self.endpoint
        if self._writes() and not endpoint.writable:
            self._answer(403, "this endpoint is read-only (stepnc-graph serve --writable allows updates)")
            return
        backend = endpoint.backend
        if backend is None:
            self._answer(503, "the endpoint is stopping")
            return
        length = int(self.headers.get("Content-Length") or 0)
        body = self.rfile.read(length) if length else None
        headers = {k: v for k, v in self.headers.items() if k.lower() not in _HOP_BY_HOP and k.lower() != "host"}
        upstream = http.client.HTTPConnection("127.0.0.1", backend.port, timeout=endpoint.timeout + 30)
        try:
            started = time.monotonic()
            upstream.request(self.command, self.path, body=body, headers=headers)
            response = upstream.getresponse()
            data = response.read(endpoint.max_bytes + 1)
            if time.monotonic() - started >= endpoint.timeout or data.rstrip().endswith(_CANCELLED):
                # Oxigraph cancels a query at its timeout after it sent "200 OK" and part of the
                # result: a client must not take that for an answer
                self._answer(503, f"the query took longer than {endpoint.timeout} s and was cancelled "
                                  "(serve --timeout sets the limit)")
                return
            if len(data) > endpoint.max_bytes:
                self._answer(507, f"the result is larger than {endpoint.max_bytes} bytes: ask for less (LIMIT, a "
                                  "narrower graph), or start serve with a larger --max-bytes")
                return
            self.send_response(response.status, response.reason)
            for key, value in response.getheaders():
                if key.lower() not in _HOP_BY_HOP:
                    self.send_header(key, value)
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            if self.command != "HEAD":
                self.wfile.write(data)
        except (OSError, http.client.HTTPException) as e:
            self._answer(502, f"the Oxigraph server did not answer: {e}")
        finally:
            upstream.close()


def is_loopback(host: str) -> bool:
    return host in LOOPBACK


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except OSError:
        return False
    return True
