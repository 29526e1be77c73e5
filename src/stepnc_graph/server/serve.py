"""``stepnc-graph serve``: the store as a SPARQL 1.1 Protocol endpoint, by Oxigraph's own server.

The SPARQL work is Oxigraph's server (``oxigraph serve-read-only``, from the
``oxigraph`` PyPI package) running over the store's published generation: the
SPARQL 1.1 Protocol for queries, the Graph Store Protocol for reading graphs,
its query timeout. In front of it sits a thin forwarding layer, because
Oxigraph's server has no result-size limit and a store's published state moves
on with every load (the forwarding layer is :mod:`.guard`; this module runs the servers):

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
import ipaddress
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from stepnc_graph.store import GraphStore, StoreError
from stepnc_graph.store.locks import Locks
from stepnc_graph.server.guard import LOOPBACK, Forward, Server, host_names, is_loopback

__all__ = ["DEFAULT_MAX_BYTES", "DEFAULT_MAX_REQUEST_BYTES", "DEFAULT_TIMEOUT", "LOOPBACK", "Endpoint", "ServeError",
           "free_port", "is_loopback", "oxigraph_binary"]


#: result bytes above which a response is refused (a browser or script asking for a whole store)
DEFAULT_MAX_BYTES = 100 << 20
#: request body bytes above which a request is refused (413): every body is read whole before it
#: is checked and forwarded, so this bounds the memory one request takes
DEFAULT_MAX_REQUEST_BYTES = 16 << 20
DEFAULT_TIMEOUT = 60


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


def _drain(process: subprocess.Popen[bytes]) -> None:
    """Read the Oxigraph server's standard error until it stops: it writes a line for every error
    while streaming a result, and a full pipe would block it."""
    if process.stderr is not None:
        for _ in process.stderr:
            pass


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
        Locks.release(self.lock_fd)
        self.lock_fd = None


class Endpoint:
    """The SPARQL endpoint over a store directory (see the module docstring)."""

    def __init__(self, store: Path, host: str = "127.0.0.1", port: int = 7878, *, writable: bool = False,
                 timeout: int = DEFAULT_TIMEOUT, max_bytes: int = DEFAULT_MAX_BYTES, union_default_graph: bool = False,
                 follow: bool = True, poll: float = 1.0, max_request_bytes: int = DEFAULT_MAX_REQUEST_BYTES,
                 allow_service: bool = False, allow_hosts: tuple[str, ...] = ()) -> None:
        self.store = store
        self.host, self.port = host, port
        self.writable, self.timeout, self.max_bytes = writable, timeout, max_bytes
        self.union_default_graph, self.follow, self.poll = union_default_graph, follow, poll
        self.max_request_bytes, self.allow_service = max_request_bytes, allow_service
        self.allowed_hosts = host_names(host, allow_hosts)
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
                    threading.Thread(target=_drain, args=(process,), daemon=True).start()
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
            fd = Locks.try_lock(self.store / f"{current}.lock", shared=True)
            if fd is not None and (self.store / current).is_dir():
                return current, fd
            Locks.release(fd)
            time.sleep(0.01)
        raise ServeError(f"cannot get a consistent view of {self.store}")

    def _read_only_backend(self) -> _Backend:
        with GraphStore(self.store, readonly=True, create=False):  # checks the store (and migrates format 1)
            pass
        generation, fd = self._pinned_generation()
        try:
            return self._start_backend(self.store / generation, fd)
        except BaseException:
            Locks.release(fd)
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
            self._writer = GraphStore(self.store, readonly=False, create=False)
            location = self._writer.serving()
            self.backend = self._start_backend(location, None)
        else:
            self.backend = self._read_only_backend()
        handler = type("Handler", (Forward,), {"endpoint": self})
        try:
            self._httpd = Server((self.host, self.port), handler)
        except OSError as e:
            self.stop()
            raise ServeError(f"cannot listen on {self.host}:{self.port}: {e.strerror or e}") from None
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

    def host_allowed(self, authority: str) -> bool:
        """Whether a request's Host (``name[:port]``) names this endpoint: a name it answers to
        (:attr:`allowed_hosts`) or an IP address. A web page whose own name was made to point at
        this machine (DNS rebinding) sends its name, which is refused."""
        name = authority.strip().lower()
        if name.startswith("["):
            name = name[1:].partition("]")[0]
        elif name.count(":") == 1:
            name = name.partition(":")[0]
        name = name.rstrip(".")
        if name in self.allowed_hosts:
            return True
        try:
            ipaddress.ip_address(name)
        except ValueError:
            return False
        return True
