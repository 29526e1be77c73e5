"""A Virtuoso server for the live tests and benchmarks: ``virtuoso-t`` (Debian package
``virtuoso-opensource-7-bin``) on free loopback ports, with a configuration written here into
its own directory, stopped by its pid.

Virtuoso serves SPARQL query and update at ``/sparql`` and the Graph Store Protocol at
``/sparql-graph-crud``; its anonymous SPARQL user is granted updates once it runs.
"""

from __future__ import annotations

import shutil
import subprocess
import time
import urllib.request
from pathlib import Path

from oxigraph_server import ServerProcess, ServerUnavailable, free_port

__all__ = ["VirtuosoServer"]

_INI = """\
[Database]
DatabaseFile = {d}/virtuoso.db
ErrorLogFile = {d}/virtuoso.log
LockFile = {d}/virtuoso.lck
TransactionFile = {d}/virtuoso.trx
xa_persistent_file = {d}/virtuoso.pxa
ErrorLogLevel = 7
FileExtend = 200
MaxCheckpointRemap = 2000
Striping = 0
TempStorage = TempDatabase

[TempDatabase]
DatabaseFile = {d}/virtuoso-temp.db
TransactionFile = {d}/virtuoso-temp.trx
MaxCheckpointRemap = 2000
Striping = 0

[Parameters]
ServerPort = 127.0.0.1:{isql}
ServerThreads = 10
CheckpointInterval = 60
NumberOfBuffers = 20000
MaxDirtyBuffers = 15000
DirsAllowed = ., {d}

[HTTPServer]
ServerPort = 127.0.0.1:{http}
ServerRoot = {d}
ServerThreads = 10
MaxClientConnections = 10
MaxKeepAlives = 10
KeepAliveTimeout = 10

[SPARQL]
ResultSetMaxRows = 1000000
MaxQueryCostEstimationTime = 0
MaxQueryExecutionTime = 0
DefaultQuery = SELECT * WHERE {{ ?s ?p ?o }} LIMIT 10
"""


class VirtuosoServer(ServerProcess):
    """``virtuoso-t`` on free loopback ports, its database in ``location``."""

    name = "virtuoso"

    def __init__(self, location: Path) -> None:
        self.location = location
        self.port = free_port()
        self.isql_port = free_port()
        self.process = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/sparql"

    @property
    def options(self) -> list[str]:
        """The CLI options that reach this server (its URLs do not follow Oxigraph's layout)."""
        return ["--query-url", self.url, "--update-url", self.url,
                "--store-url", f"http://127.0.0.1:{self.port}/sparql-graph-crud"]

    def start(self) -> None:
        binary = shutil.which("virtuoso-t")
        if binary is None or shutil.which("isql-vt") is None:
            raise ServerUnavailable("virtuoso-t is not installed (Debian: apt-get install virtuoso-opensource-7-bin)")
        self.location.mkdir(parents=True, exist_ok=True)
        ini = self.location / "virtuoso.ini"
        ini.write_text(_INI.format(d=self.location, isql=self.isql_port, http=self.port))
        self.process = subprocess.Popen([binary, "+foreground", "+configfile", str(ini)], cwd=self.location,
                                        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            self._wait(60)
            self.isql('GRANT SPARQL_UPDATE TO "SPARQL";')
        except ServerUnavailable:
            self.stop()
            raise

    def isql(self, statement: str) -> str:
        """Run one SQL statement as dba (the default password of a fresh database)."""
        done = subprocess.run(["isql-vt", str(self.isql_port), "dba", "dba", f"exec={statement}"],
                              capture_output=True, text=True, timeout=120)
        if done.returncode != 0:
            raise ServerUnavailable(f"isql-vt {statement!r} failed: {done.stderr or done.stdout}")
        return done.stdout

    def _wait(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            assert self.process is not None
            if self.process.poll() is not None:
                log = self.location / "virtuoso.log"
                tail = log.read_text(errors="replace")[-500:] if log.exists() else ""
                raise ServerUnavailable(f"virtuoso-t exited with {self.process.returncode}: {tail}")
            try:
                with urllib.request.urlopen(f"{self.url}?query=ASK%7B%7D", timeout=2):
                    return
            except OSError:
                time.sleep(0.2)
        raise ServerUnavailable(f"{self.url} did not answer within {seconds:.0f} s")
