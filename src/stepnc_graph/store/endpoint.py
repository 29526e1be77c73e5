"""Where a remote store answers: its URLs, the credentials from the environment, TLS, timeouts."""

from __future__ import annotations

import base64
import os
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit, urlunsplit

from stepnc_graph.store import StoreError

ENDPOINT_ENV = "STEPNC_GRAPH_ENDPOINT"
TOKEN_ENV = "STEPNC_GRAPH_ENDPOINT_TOKEN"
USER_ENV, PASSWORD_ENV = "STEPNC_GRAPH_ENDPOINT_USER", "STEPNC_GRAPH_ENDPOINT_PASSWORD"
AUTH_ENV = "STEPNC_GRAPH_ENDPOINT_AUTH"
CA_ENV = "STEPNC_GRAPH_CA_BUNDLE"
RETRIES_ENV = "STEPNC_GRAPH_RETRIES"
TIMEOUT_ENV = "STEPNC_GRAPH_TIMEOUT"
#: seconds to wait for the whole answer to one request (a load's final swap of a large program
#: takes tens of seconds on Oxigraph: 21 s for 700k quads)
DEFAULT_TIMEOUT = 120.0
#: seconds to wait for a connection
CONNECT_TIMEOUT = 10.0

@dataclass(frozen=True)
class Endpoint:
    """Where a remote store answers: the three URLs, credentials from the environment, TLS."""

    query_url: str
    update_url: str
    store_url: str
    headers: dict[str, str] = field(default_factory=dict, repr=False)  # repr=False: never print credentials
    auth: tuple[str, str] | None = field(default=None, repr=False)
    #: how a user and password are sent: "basic", "digest", or "" (Basic, Digest once the server asks for it)
    scheme: str = ""
    verify: bool | str = True
    timeout: float = DEFAULT_TIMEOUT
    retries: int = 5

    @classmethod
    def from_options(cls, base: str, query_url: str | None = None, update_url: str | None = None,
                     store_url: str | None = None, timeout: float | None = None) -> "Endpoint":
        """URLs from a base (Oxigraph's layout: ``BASE/query``, ``BASE/update``, ``BASE/store``)
        or given one by one (Fuseki: ``/ds/query``, ``/ds/update``, ``/ds/data``); ``timeout``
        (seconds) or ``$STEPNC_GRAPH_TIMEOUT`` or :data:`DEFAULT_TIMEOUT`."""
        urls = [u for u in (base, query_url, update_url, store_url) if u]
        for url in urls:
            parts = urlsplit(url)
            if parts.scheme not in ("http", "https") or not parts.netloc:
                raise StoreError(f"endpoint {_safe(url)!r} is not an http(s) URL")
            if parts.username or parts.password:
                raise StoreError("an endpoint URL must not hold a user or password (they would land in shell "
                                 f"history): set {TOKEN_ENV}, or {USER_ENV} and {PASSWORD_ENV}")
        root = base.rstrip("/")
        if root.endswith("/query"):  # given the query endpoint itself: its siblings
            root = root[: -len("/query")]
        token, user, password = os.environ.get(TOKEN_ENV), os.environ.get(USER_ENV), os.environ.get(PASSWORD_ENV)
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        retries = os.environ.get(RETRIES_ENV, "").strip()
        scheme = os.environ.get(AUTH_ENV, "").strip().lower()
        if scheme not in ("", "basic", "digest"):
            raise StoreError(f"{AUTH_ENV}={scheme!r}: expected basic or digest")
        ca_bundle = os.environ.get(CA_ENV)
        if ca_bundle and not Path(ca_bundle).exists():
            raise StoreError(f"{CA_ENV} names {ca_bundle}, which does not exist")
        return cls(query_url or f"{root}/query", update_url or f"{root}/update", store_url or f"{root}/store",
                   headers, (user, password or "") if user and not token else None,
                   scheme, ca_bundle or True, timeout=_timeout(timeout),
                   retries=int(retries) if retries.isdigit() else 5)

    def secrets(self) -> list[str]:
        """The credentials as they may appear in text: to be removed from every message."""
        found = [v.split(" ", 1)[-1] for v in self.headers.values()]
        if self.auth is not None:
            user, password = self.auth
            found += [password, base64.b64encode(f"{user}:{password}".encode()).decode()]
        return [f for f in found if len(f) >= 4]  # a 1-3 character secret would blank ordinary words

    def __str__(self) -> str:
        return _safe(self.query_url)


def _timeout(given: float | None) -> float:
    """The request timeout: given, else ``$STEPNC_GRAPH_TIMEOUT``, else the default; positive."""
    if given is None:
        text = os.environ.get(TIMEOUT_ENV, "").strip()
        try:
            given = float(text) if text else DEFAULT_TIMEOUT
        except ValueError:
            raise StoreError(f"{TIMEOUT_ENV}={text!r}: expected a number of seconds") from None
    if not given > 0:
        raise StoreError(f"the endpoint timeout must be a positive number of seconds, not {given}")
    return given


def _safe(url: str) -> str:
    """``url`` without user, password or query string (for messages)."""
    parts = urlsplit(url)
    host = parts.hostname or ""
    return urlunsplit((parts.scheme, host + (f":{parts.port}" if parts.port else ""), parts.path, "", ""))
