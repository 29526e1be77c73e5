"""The HTTP layer of :class:`~stepnc_graph.store.remote.RemoteStore`: one session with the
endpoint's credentials and CA, requests retried with exponential backoff on transient failures
(but never a write the endpoint may have carried out), whole answers read within the timeout,
HTTP Digest taken up when the server asks for it, credentials kept out of every message."""

from __future__ import annotations

import re
import time
from typing import Any

from stepnc_graph.store.answers import RemoteError
from stepnc_graph.store.endpoint import CA_ENV, CONNECT_TIMEOUT, TIMEOUT_ENV, Endpoint, _safe

_TRANSIENT = {429, 502, 503, 504}


def _software(header: str) -> str | None:
    """A ``Server`` header as text fit for a message: no control characters, at most 120 long."""
    return re.sub(r"[\x00-\x1f\x7f]", "", header).strip()[:120] or None


class HttpClient:
    """Requests to one endpoint; ``server`` is its ``Server`` header, from its first answer that named one."""

    def __init__(self, endpoint: Endpoint) -> None:
        import requests

        self.endpoint = endpoint
        self.server: str | None = None
        self.session = requests.Session()
        self.session.headers.update(endpoint.headers)
        if endpoint.auth is not None:
            self.session.auth = (requests.auth.HTTPDigestAuth(*endpoint.auth) if endpoint.scheme == "digest"
                                 else requests.auth.HTTPBasicAuth(*endpoint.auth))
        self.session.verify = endpoint.verify

    def close(self) -> None:
        self.session.close()

    def redact(self, text: str) -> str:
        """``text`` without the credentials (an error body may echo the request's headers)."""
        for secret in self.endpoint.secrets():
            text = text.replace(secret, "***")
        return text

    def request(self, method: str, url: str, *, idempotent: bool = True, stream: bool = False,
                **kwargs: Any) -> tuple[Any, bytes | None]:
        """One HTTP request and its answer's body (None when ``stream``), retried with backoff on
        transient failures; raises RemoteError.

        A request that is not ``idempotent`` (it writes) is sent again only when the endpoint
        cannot have carried it out: no connection was made, or it answered 429 or 503. No request
        is sent again after the endpoint kept silent for the whole timeout."""
        import requests

        delay = 0.5
        timeout = self.endpoint.timeout
        for attempt in range(self.endpoint.retries + 1):
            retry = True
            try:
                # verify given here: requests lets REQUESTS_CA_BUNDLE override the session's value
                response = self.session.request(method, url, timeout=(min(CONNECT_TIMEOUT, timeout), timeout),
                                                verify=self.endpoint.verify, stream=True, **kwargs)
                content = None if stream and response.status_code < 400 else _content(response, timeout)
            except requests.Timeout as e:
                if not isinstance(e, requests.ConnectTimeout):
                    written = "" if idempotent else "; it may have been carried out"
                    raise RemoteError(f"{method} {_safe(url)} did not answer within {timeout:g} s (--timeout or "
                                      f"${TIMEOUT_ENV} sets the limit){written}") from None
                failure = f"{_safe(url)} does not answer (no connection within {min(CONNECT_TIMEOUT, timeout):g} s)"
            except requests.exceptions.SSLError as e:
                reason = str(e.args[0].reason if e.args and hasattr(e.args[0], "reason") else e)[:200]
                raise RemoteError(f"{_safe(url)}: TLS failed ({reason}); ${CA_ENV} names the CA file of a private "
                                  "PKI") from None
            except requests.ConnectionError as e:
                failure = f"{type(e).__name__}: {_safe(url)} does not answer"
                retry = idempotent or _nothing_sent(e)
            except requests.exceptions.ChunkedEncodingError:  # the connection broke during the answer
                failure = f"{_safe(url)} does not answer (the connection broke during its answer)"
                retry = idempotent
            except requests.RequestException as e:
                raise RemoteError(self.redact(f"{method} {_safe(url)} failed: {e}")) from None
            else:
                if response.status_code < 400:
                    self.server = self.server or _software(response.headers.get("Server", ""))
                    return response, content
                if self._digest_asked(response):  # the server named the scheme: sent again with Digest, once
                    return self.request(method, url, idempotent=idempotent, stream=stream, **kwargs)
                body = (content or b"")[:300].decode("utf-8", "replace").strip()
                failure = self.redact(f"{method} {_safe(url)} answered {response.status_code}: {body}")
                retry = response.status_code in _TRANSIENT and (idempotent or response.status_code in (429, 503))
            if not retry:
                raise RemoteError(failure)
            if attempt < self.endpoint.retries:
                time.sleep(delay)
                delay *= 2
        raise RemoteError(f"{failure} (after {self.endpoint.retries + 1} attempts)")

    def _digest_asked(self, response: Any) -> bool:
        """Whether a 401 asks for HTTP Digest where Basic was sent (:data:`~stepnc_graph.store.endpoint.AUTH_ENV` unset): then
        the session answers with Digest from now on (Virtuoso's authenticated endpoints)."""
        import requests

        challenge = response.headers.get("WWW-Authenticate", "").lower()
        if (response.status_code != 401 or self.endpoint.auth is None or self.endpoint.scheme
                or not challenge.startswith("digest") or isinstance(self.session.auth, requests.auth.HTTPDigestAuth)):
            return False
        self.session.auth = requests.auth.HTTPDigestAuth(*self.endpoint.auth)
        return True


def _content(response: Any, timeout: float) -> bytes:
    """The whole body of a streamed ``response``, read within ``timeout`` seconds however slowly
    it comes (requests' own timeout bounds each read, not the whole)."""
    import requests

    deadline = time.monotonic() + timeout
    parts = []
    with response:
        for part in response.iter_content(1 << 16):
            parts.append(part)
            if time.monotonic() > deadline:
                raise requests.ReadTimeout("the answer did not end in time")
    return b"".join(parts)


def _nothing_sent(error: Exception) -> bool:
    """Whether a connection error happened before the request was sent (no connection made)."""
    from urllib3.exceptions import NewConnectionError

    reason = getattr(error.args[0], "reason", None) if error.args else None
    return isinstance(reason, NewConnectionError) or "NewConnectionError" in str(error)
