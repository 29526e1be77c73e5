"""A replacement over the SPARQL protocol by difference: only the quads that changed are written.

A replacement that drops a program's graphs and inserts the new version makes the server delete
and re-index every quad, although a program loaded again usually differs in a few lines (its
load's time, an edited value). Here (:func:`replace_by_difference`) the old version is read
(one Graph Store GET per graph, N-Triples), compared line by line with the new version staged in
the client, and one SPARQL Update deletes what went and inserts what came.

**Compare-and-swap.** Between the GET and the update another client may replace the graph. Every
load the client stages writes a fresh load id into a bookkeeping graph of its own
(:func:`token_graph`, a staging name: no listing, export or count sees it), written in the same
request as the program. The update's WHERE clause requires the old load id, and the update
replaces it by the new one: if someone else wrote in between, the update matches nothing and
changes nothing. That is read back (the new id present, every graph's count the staged one); if
not, the caller replaces the graphs whole, in one request, so the last writer wins and the graph
is never a mix of two loads.

**Blank nodes** (list cells and typed values of the program, which the derived layer points at)
cannot be named across requests. They are first matched between the versions by their place under
the instance that owns them (:class:`~stepnc_graph.store.difference.BlankMatch`, as the embedded
replacement does), so an unchanged list compares equal. A changed line that names an old blank
node reaches it in the WHERE clause by its path from its named owner -- each step a property with
one blank-node value there -- and a new blank node is a label of the INSERT template (one
operation: it stays one node across the graphs). A line whose old blank node has no such path
(a member of a SET of lists, a node reached twice) makes the caller replace the graphs whole.
"""

from __future__ import annotations

import hashlib
import tempfile
import threading
import uuid
from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyoxigraph as ox

from stepnc_graph.core.naming import STAGING, VOCABULARY_GRAPH
from stepnc_graph.store.difference import BlankMatch
from stepnc_graph.store.errors import StoreError
from stepnc_graph.store.kept import BLANK_OBJECT

if TYPE_CHECKING:
    from stepnc_graph.store.remote import RemoteStore

#: the property of a load's id in its :func:`token_graph`
LOAD_ID = STAGING + "loadId"

#: a difference of more lines than this share of the new version's is written whole instead: the
#: update would then cost about what the full replacement costs
MOST_CHANGED = 0.5


def token_graph(graph: str) -> str:
    """The bookkeeping graph holding the id of ``graph``'s last load (a staging name, hidden from
    every listing; not of the form of a load's staging graphs, which stale-staging clean-up drops)."""
    return f"{STAGING}load:{hashlib.sha256(graph.encode('utf-8')).hexdigest()[:32]}"


def token_line(graph: str, load_id: str) -> str:
    """The N-Triples line recording ``load_id`` as ``graph``'s last load."""
    return f"{ox.NamedNode(graph)} <{LOAD_ID}> {ox.Literal(load_id)} .\n"


def new_load_id() -> str:
    return uuid.uuid4().hex


def last_load_id(store: RemoteStore, graph: str) -> str | None:
    """The id of ``graph``'s last load as the store holds it; None if none, or not one."""
    rows = list(store.query(f"SELECT ?id WHERE {{ GRAPH <{token_graph(graph)}> {{ {ox.NamedNode(graph)} "
                            f"<{LOAD_ID}> ?id }} }}"))
    return rows[0][0].value if len(rows) == 1 and isinstance(rows[0][0], ox.Literal) else None


class OldVersion:
    """The old version of a program's graphs (its load id, then each graph's N-Triples lines),
    read on a thread and a connection of its own while the client stages the new one: the
    server writes them out meanwhile (a replicated real 10k-instance program's two graphs: 22 MB,
    1.7 s of a replacement's wall time when read after the staging). The id is read first, so
    lines read after another client's write go with an id that the update's condition then
    finds gone."""

    def __init__(self, store: RemoteStore, names: list[str]) -> None:
        self.names = names
        self.load_id: str | None = None
        self.lines: dict[str, set[bytes]] = {}
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._read, args=(type(store)(store.endpoint),), daemon=True)
        self._thread.start()

    def _read(self, reader: RemoteStore) -> None:
        try:
            with reader:
                self.load_id = last_load_id(reader, self.names[0])
                if self.load_id is not None:
                    self.lines = {name: _lines(reader.ntriples(name)) for name in self.names}
        except BaseException as exc:  # noqa: BLE001 -- raised by read()
            self._error = exc

    def read(self) -> tuple[str | None, dict[str, set[bytes]]]:
        """The load id and the lines of each graph (no lines: no load id). A store's error is
        raised (the caller then replaces the graphs whole, which says it again if it lasts)."""
        self._thread.join()
        if self._error is not None:
            raise self._error
        return self.load_id, self.lines


def replace_by_difference(store: RemoteStore, local: Any, staging: dict[str, str], most: int,
                          before: OldVersion) -> str | None:
    """Make the graphs of ``staging`` (name in the store -> staged name in ``local``; the program's
    graph first, its :func:`token_graph` among them) what ``local`` holds by writing only what
    changed since ``before`` (see the module docstring), in one update of at most ``most`` lines.
    None once done; else why the caller must replace them whole, having changed nothing (or what
    another client's load then overwrote): no load id to compare with, the vocabulary graph
    rewritten, most lines changed, an old blank node without a path, or another client wrote in
    between."""
    main = next(iter(staging))
    tokens = token_graph(main)
    if tokens not in staging:
        return "no load id written"
    if VOCABULARY_GRAPH in staging:
        return "the vocabulary graph is rewritten"
    try:
        old_id, old = before.read()
    except StoreError as exc:
        return f"the old version could not be read ({exc})"
    if old_id is None:
        return "no load id to compare with"
    if set(old) != set(staging):
        return "other graphs than those read"
    new = {name: _lines(_dump(local, tmp)) for name, tmp in staging.items()}
    staged = {name: len(lines) for name, lines in new.items()}
    new_id = next(iter(new[tokens])).split(b'"')[1].decode("utf-8")
    match = _match(old[main], new[main])
    changed = {name: (_difference(old[name], new.pop(name), match)) for name in staging}
    lines = sum(len(gone) + len(came) for gone, came in changed.values())
    if lines > MOST_CHANGED * sum(staged.values()) or lines > most:
        return "most lines changed"
    paths = Paths(old[main], _labels(line for lines in old.values() for line in lines))
    update = paths.update(main, changed, old_id)
    if update is None:
        return "a changed line names a blank node without a path"
    store.update(update)
    if last_load_id(store, main) != new_id:
        return "another load wrote in between"
    if any(store.count(name) != count for name, count in staged.items()):
        return "the counts did not come out as staged"
    return None


def _blanks(line: bytes) -> list[tuple[int, int, bytes]]:
    """The blank nodes of an N-Triples line as Oxigraph writes it, subject first: each one's
    span (from its ``_:``) and its label."""
    if b"_:" not in line:
        return []
    found = []
    if line.startswith(b"_:"):
        end = line.index(b" ")
        found.append((0, end, line[2:end]))
    if (m := BLANK_OBJECT.search(line)) is not None:
        found.append((m.start(1) - 2, m.end(1), m.group(1)))
    return found


def _labels(lines: Iterable[bytes]) -> set[bytes]:
    """The blank node labels of N-Triples lines (subjects and objects)."""
    return {label for line in lines for _, _, label in _blanks(line)}


def _lines(text: bytes) -> set[bytes]:
    """The lines of N-Triples text (each once: a graph holds a triple once), as a set -- the
    old and the new version of a 100k-instance program are 1.3M lines each."""
    return set(text.splitlines(keepends=True))


def _dump(local: Any, staged: str) -> bytes:
    """The staged graph as N-Triples (empty: no such graph)."""
    quads = local.oxigraph.quads_for_pattern(None, None, None, ox.NamedNode(staged))
    return ox.serialize((q.triple for q in quads), format=ox.RdfFormat.N_TRIPLES) or b""


def _match(old: set[bytes], new: set[bytes]) -> BlankMatch:
    """:class:`BlankMatch` of the program graph's two versions (it reads files)."""
    with tempfile.TemporaryDirectory(prefix="stepnc-difference-") as scratch:
        paths = Path(scratch) / "old.nt", Path(scratch) / "new.nt"
        for path, lines in zip(paths, (old, new), strict=True):
            with open(path, "wb", buffering=1 << 20) as out:
                out.writelines(lines)
        return BlankMatch(*paths)


def _difference(old: set[bytes], new: set[bytes], match: BlankMatch) -> tuple[list[bytes], list[bytes]]:
    """The old lines the new version lacks and its lines (blank nodes named as ``match`` gives)
    the old version lacks."""
    after = {match.relabel(line) if b"_:" in line else line for line in new}
    return sorted(old - after), sorted(after - old)


class Paths:
    """How the update reaches each old blank node of a program graph: from the named instance
    that owns it, one property at a time, each a property with one blank-node value on its
    subject there (so the pattern binds that node alone)."""

    def __init__(self, lines: Iterable[bytes], old: set[bytes]) -> None:
        #: blank label -> (its subject, the property), for a node reached by one triple
        self.parent: dict[bytes, tuple[bytes, bytes]] = {}
        reached: Counter[bytes] = Counter()
        values: Counter[tuple[bytes, bytes]] = Counter()  # (subject, property) -> blank values
        for line in lines:
            if b"_:" in line and (m := BLANK_OBJECT.search(line)) is not None:
                subject, prop, _ = line.split(b" ", 2)
                reached[m.group(1)] += 1
                values[subject, prop] += 1
                self.parent[m.group(1)] = (subject, prop)
        self.parent = {label: up for label, up in self.parent.items() if reached[label] == 1 and values[up] == 1}
        #: every blank label of the old version (of any graph): the others are new nodes
        self.old = old
        self._bound: dict[bytes, str] = {}
        self._where: list[str] = []

    def bind(self, label: bytes) -> str | None:
        """The variable bound to old blank node ``label`` (its path added to the WHERE clause),
        None if it has no path."""
        chain: list[bytes] = []
        seen: set[bytes] = set()
        node = label
        while node not in self._bound:
            up = self.parent.get(node)
            if up is None or node in seen:  # no path, or a cycle of blank nodes
                return None
            chain.append(node)
            seen.add(node)
            if not up[0].startswith(b"_:"):
                break
            node = up[0][2:]
        for below in reversed(chain):
            subject, prop = self.parent[below]
            above = self._bound[subject[2:]] if subject.startswith(b"_:") else subject.decode("utf-8")
            var = self._bound[below] = f"?b{len(self._bound)}"
            self._where.append(f"{above} {prop.decode('utf-8')} {var} . FILTER(isBlank({var}))")
        return self._bound[label]

    def template(self, line: bytes) -> str | None:
        """``line`` for the update's templates: an old blank node as its bound variable, a new one
        as a label of the template; None if an old one has no path."""
        for start, end, label in reversed(_blanks(line)):
            term = self.bind(label) if label in self.old else "_:n" + label.decode("ascii")
            if term is None:
                return None
            line = line[:start] + term.encode("utf-8") + line[end:]
        return line.decode("utf-8")

    def update(self, main: str, changed: dict[str, tuple[list[bytes], list[bytes]]], old_id: str) -> str | None:
        """One SPARQL Update writing ``changed`` (graph -> (lines gone, lines come)) only if the
        store still holds load ``old_id`` of ``main``; None if an old blank node has no path."""
        parts: dict[str, list[str]] = {"DELETE": [], "INSERT": []}
        for name, (gone, came) in changed.items():
            for key, lines in (("DELETE", gone), ("INSERT", came)):
                if not lines:
                    continue
                texts = [self.template(line) for line in lines]
                if any(t is None for t in texts):
                    return None
                parts[key].append(f"GRAPH {ox.NamedNode(name)} {{\n{''.join(t for t in texts if t)}}}")
        where = (f"GRAPH <{token_graph(main)}> {{ {ox.NamedNode(main)} <{LOAD_ID}> {ox.Literal(old_id)} }}\n"
                 + (f"GRAPH {ox.NamedNode(main)} {{\n" + "\n".join(self._where) + "\n}" if self._where else ""))
        return "\n".join(f"{key} {{\n" + "\n".join(graphs) + "\n}" for key, graphs in parts.items() if graphs
                         ) + f"\nWHERE {{\n{where}\n}}"
