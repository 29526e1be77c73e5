"""A real SPARQL endpoint for the benchmarks and tests: Oxigraph's own server (``oxigraph serve``,
from the ``oxigraph`` PyPI package, a test extra) on a free loopback port, stopped by its pid."""

from __future__ import annotations

import os
import signal
import subprocess
import time
import urllib.request
from pathlib import Path

from stepnc_graph.server.serve import ServeError, free_port, oxigraph_binary

__all__ = ["OxigraphServer", "ServerProcess", "ServerUnavailable", "free_port", "oxigraph_server_binary", "wait_until_answers"]

TICKS = os.sysconf("SC_CLK_TCK")


class ServerUnavailable(Exception):
    """The server is not installed here, or did not start (the message says which)."""


def wait_until_answers(url: str, process: subprocess.Popen[bytes] | None = None, seconds: float = 30) -> None:
    """Wait until ``url/query`` answers a SPARQL ASK; ServerUnavailable if ``process`` exits or time runs out."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if process is not None and process.poll() is not None:
            raise ServerUnavailable(f"{process.args} exited with {process.returncode}")
        try:
            with urllib.request.urlopen(f"{url}/query?query=ASK%7B%7D", timeout=1):
                return
        except OSError:
            time.sleep(0.1)
    raise ServerUnavailable(f"{url} did not answer within {seconds:.0f} s")


def oxigraph_server_binary() -> str:
    """The ``oxigraph`` program, found as ``stepnc-graph serve`` finds it."""
    try:
        return oxigraph_binary()
    except ServeError as exc:
        raise ServerUnavailable(str(exc)) from None


class ServerProcess:
    """A server the tests and benchmarks start as a child process: its CPU time and how it stops,
    the same for every store (Oxigraph's server, Virtuoso)."""

    process: subprocess.Popen[bytes] | None = None

    def cpu(self) -> float:
        """User + system CPU seconds the server has used (Linux /proc)."""
        assert self.process is not None
        fields = Path(f"/proc/{self.process.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / TICKS

    def stop(self, sig: int = signal.SIGTERM) -> None:
        """Send ``sig`` and wait for the server to end; one that outlives a minute is killed."""
        if self.process is not None and self.process.poll() is None:
            os.kill(self.process.pid, sig)
            try:
                self.process.wait(timeout=60)
            except subprocess.TimeoutExpired:
                os.kill(self.process.pid, signal.SIGKILL)
                self.process.wait(timeout=60)
        self.process = None


class OxigraphServer(ServerProcess):
    """``oxigraph serve`` on a free loopback port, persistent in ``location``."""

    def __init__(self, location: Path) -> None:
        self.location = location
        self.port = free_port()
        self.process = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def start(self) -> None:
        self.process = subprocess.Popen([oxigraph_server_binary(), "serve", "--location", str(self.location),
                                         "--bind", f"127.0.0.1:{self.port}"], stdout=subprocess.DEVNULL,
                                        stderr=subprocess.DEVNULL)
        try:
            wait_until_answers(self.url, self.process)
        except ServerUnavailable:
            self.stop()
            raise

