"""Damaged JSON-LD inputs and the checks every load of one must pass (:mod:`.fuzz`).

A damaged JSON-LD input (:func:`mutate_jsonld`) is an exported program document
with contexts that name a URL (nested arrays, ``@import``, scoped contexts),
huge numbers, ``@id`` IRIs with a NUL or a space, deep nesting or a long
``@list``. :func:`check_jsonld` loads it and fails on an exception other than a
:class:`~stepnc_graph.loading.sources.SourceError`, and on any outbound connection: the
URLs point at a :class:`LoopbackListener` that must receive nothing, and an
audit hook records any socket the process opens meanwhile.
"""

from __future__ import annotations

import json
import random
import socket
import sys
import tempfile
import threading
from pathlib import Path
from typing import Any

from stepnc_graph.testing.fuzz_part21 import Outcome, basic_damage


JSONLD_KINDS = ["jsonld-context", "jsonld-number", "jsonld-iri", "jsonld-nesting", "jsonld-list", "jsonld-bytes"]


class LoopbackListener:
    """A TCP listener on 127.0.0.1 that counts the connections it receives: a URL of it placed
    in a document must receive none (a load never goes to the network)."""

    def __init__(self) -> None:
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._socket.bind(("127.0.0.1", 0))
        self._socket.listen(16)
        self.port = self._socket.getsockname()[1]
        self.connections = 0
        threading.Thread(target=self._serve, daemon=True).start()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/context.jsonld"

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self._socket.accept()
            except OSError:
                return
            self.connections += 1
            conn.close()

    def close(self) -> None:
        self._socket.close()


_SOCKET_EVENTS = frozenset({"socket.connect", "socket.getaddrinfo", "socket.gethostbyname", "urllib.Request",
                            "http.client.connect"})
_watch: list[str] | None = None  # while a check runs: the network events seen


def _audit(event: str, args: tuple[Any, ...]) -> None:
    if _watch is not None and event in _SOCKET_EVENTS:
        _watch.append(f"{event} {args[1:2] if event == 'socket.connect' else args[:1]}"[:200])


_hooked = False


def watch_network() -> None:
    """Install (once per process) the audit hook that records socket use during a check."""
    global _hooked
    if not _hooked:
        sys.addaudithook(_audit)
        _hooked = True


def mutate_jsonld(rng: random.Random, doc: bytes, url: str, kinds: list[str] | None = None) -> tuple[str, bytes]:
    """One damaged variant of the JSON-LD document ``doc`` (an export) and the name of the damage;
    ``url`` is the loopback listener's, placed where a processor would fetch a context."""
    kind = rng.choice(kinds or JSONLD_KINDS)
    if kind == "jsonld-bytes":
        return kind, basic_damage(rng, rng.choice(["truncate", "flip", "delete", "repeat", "flips"]), doc, [])
    tree = json.loads(doc)
    raw: dict[str, str] = {}  # placeholder string -> JSON text put there after dumping
    if kind == "jsonld-context":
        _contexts(rng, tree, url, raw)
    elif kind == "jsonld-number":
        _replace_value(rng, tree, _placeholder(raw, rng.choice(
            ["9" * 5000, "-" + "9" * 20_000, "1e999999", "-1e-999999", "1." + "0" * 5000 + "1", "NaN", "Infinity",
             "1" * 300_000, "0.5e" + "9" * 5000])), numbers_only=rng.random() < 0.7)
    elif kind == "jsonld-iri":
        bad = rng.choice(["http://x/a\u0000b", "http://x/a b", "", " ", "http://x/<i1>", "a\nb", "_:", "_:b 1",
                          "http://[::1", "http://x/" + "a" * 1_000_000, "javascript:alert(1)", "http://x/%zz",
                          "\u0000", url, "file:///etc/passwd"])
        _replace_key(rng, tree, "@id", bad)
    elif kind == "jsonld-nesting":
        depth = rng.choice([100, 1000, 10_000, 100_000])
        shape = rng.choice(["[", '{"@list":[', '{"a":', '{"@set":['])
        close = {"[": "]", '{"@list":[': "]}", '{"a":': "}", '{"@set":[': "]}"}[shape]
        _replace_value(rng, tree, _placeholder(raw, shape * depth + "1" + close * depth), numbers_only=False)
    elif kind == "jsonld-list":
        n = rng.choice([1_000, 10_000, 50_000])  # the loader takes ~0.17 ms an item: 100k is 18 CPU s
        item = rng.choice(["1", "1.5", '"s"', '{"@id":"http://x/a"}', "[]"])
        _replace_value(rng, tree, _placeholder(raw, '{"@list":[' + ",".join([item] * n) + "]}"), numbers_only=False)
    text = json.dumps(tree, ensure_ascii=rng.random() < 0.5)
    for key, value in raw.items():
        text = text.replace(json.dumps(key), value)
    return kind, text.encode("utf-8", "surrogatepass")


def _placeholder(raw: dict[str, str], text: str) -> str:
    key = f"\u0001fuzz{len(raw)}\u0001"
    raw[key] = text
    return key


def _nodes(tree: Any) -> list[tuple[Any, Any]]:
    """Every (container, key) in the tree, iteratively."""
    out: list[tuple[Any, Any]] = []
    stack = [tree]
    while stack:
        node = stack.pop()
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        for key, value in items:
            out.append((node, key))
            if isinstance(value, (dict, list)):
                stack.append(value)
    return out


def _replace_value(rng: random.Random, tree: Any, value: Any, numbers_only: bool) -> None:
    places = [(c, k) for c, k in _nodes(tree) if not numbers_only or type(c[k]) in (int, float)]
    places = places or _nodes(tree)
    if places:
        container, key = rng.choice(places)
        container[key] = value


def _replace_key(rng: random.Random, tree: Any, name: str, value: Any) -> None:
    places = [(c, k) for c, k in _nodes(tree) if k == name]
    if places:
        container, key = rng.choice(places)
        container[key] = value


def _contexts(rng: random.Random, tree: Any, url: str, raw: dict[str, str]) -> None:
    """Put ``url`` where a JSON-LD processor would fetch it: the top context in nested arrays,
    an ``@import``, a scoped context (on a node or a term), a context of a nested node."""
    how = rng.choice(["nested-array", "import", "scoped-term", "node", "deep-array", "base-vocab"])
    top = tree.get("@context", {}) if isinstance(tree, dict) else {}
    if how == "nested-array":
        tree["@context"] = [[url], top] if rng.random() < 0.5 else [top, [[url, {}]]]
    elif how == "deep-array":  # as text: json.dumps recurses
        depth = rng.choice([10, 100, 1000, 100_000])
        tree["@context"] = [top, _placeholder(raw, "[" * depth + json.dumps(url) + "]" * depth)]
    elif how == "import" and isinstance(top, dict):
        top["@import"] = url
    elif how == "scoped-term" and isinstance(top, dict):
        terms = [k for k, v in top.items() if isinstance(v, dict)]
        if terms:
            top[rng.choice(terms)]["@context"] = rng.choice([url, [url], [{}, url]])
    elif how == "base-vocab" and isinstance(top, dict):
        top["@vocab"] = url
        top["@base"] = url
    else:
        objects = [c[k] for c, k in _nodes(tree) if isinstance(c[k], dict) and c[k] is not top]
        if objects:
            rng.choice(objects)["@context"] = rng.choice([url, [url], {"@import": url}])


def check_jsonld(data: bytes, listener: LoopbackListener | None = None, name: str = "fuzz.jsonld") -> Outcome:
    """Load the JSON-LD ``data``: ``rejected`` on a documented error (SourceError), ``failed`` on a
    connection (to ``listener`` or recorded by the audit hook, see :func:`watch_network`), on a
    graph whose instances are not counted, or on an export that does not parse strictly; any other
    exception propagates (the caller records it as a traceback)."""
    global _watch
    import stepnc_graph as sg
    from stepnc_graph.loading.common import SourceError

    before = listener.connections if listener is not None else 0
    seen: list[str] = []
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / name
        path.write_bytes(data)
        store = sg.open_store(memory=True)
        _watch = seen
        try:
            [r] = sg.load(store, [path])
        except SourceError:
            return _network(listener, before, seen) or Outcome("rejected")
        except Exception:
            failed = _network(listener, before, seen)  # a failed fetch is a fetch: that is what it broke
            if failed:
                return failed
            raise
        finally:
            _watch = None
    failed = _network(listener, before, seen)
    if failed:
        return failed
    return _jsonld_graph(store, r)


def _network(listener: LoopbackListener | None, before: int, seen: list[str]) -> Outcome | None:
    if listener is not None and listener.connections > before:
        return Outcome("failed", f"network: {listener.connections - before} connection(s) to the loopback listener")
    if seen:
        return Outcome("failed", f"network: {seen[0]}")
    return None


def _jsonld_graph(store: Any, r: Any) -> Outcome:
    import stepnc_graph as sg
    from stepnc_graph.core.naming import P21_NS
    from stepnc_graph.part21 import Part21SyntaxError, read_text

    ids = len(list(store.query(f"SELECT ?s WHERE {{ GRAPH <{r.graph}> {{ ?s <{P21_NS}id> ?id }} }}")))
    if ids > r.instances:
        return Outcome("failed", f"invariant: {ids} numbered instances in the graph, {r.instances} counted")
    try:
        for _ in read_text(sg.export(store, "p21", r.graph).decode("utf-8"), "exported.stp").instances():
            pass
    except Part21SyntaxError as e:
        return Outcome("failed", f"the export does not parse strictly: {e.message} (line {e.line})")
    return Outcome("ok")
