"""A replacement by difference (see :mod:`stepnc_graph.store.replacement`):
the load's text kept as it is written (:class:`Tee`), blank nodes matched between the versions
(:class:`BlankMatch`), the old lines deleted on a thread of their own (:class:`Deleter`), and
the N-Triples files compared part by part."""

from __future__ import annotations

import hashlib
import queue
import threading
import traceback
import uuid
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

import pyoxigraph as ox

from stepnc_graph.store import tuning
from stepnc_graph.store.batches import count_in
from stepnc_graph.store.kept import BLANK_OBJECT, KeptText, KeptWriting

if TYPE_CHECKING:
    from stepnc_graph.store.replacement import Replacement


class Deleter:
    """Deletes a replacement's old lines on a thread of its own, in the order given, while the
    caller compares the next part: the comparison is Python, which holds the interpreter,
    and Oxigraph's updates let go of it (measured: a 200k-line DELETE DATA took 1.2 s and a
    Python loop beside it ran at full speed). One thread, so that its flushes never run
    beside a delete (see :data:`~stepnc_graph.store.tuning.FLUSH_DELETES`). The first error stops it and is raised by
    :meth:`finish`."""

    def __init__(self, replacement: Replacement) -> None:
        self._replacement = replacement
        self._work: queue.Queue[Callable[[], None] | None] = queue.Queue()
        self._error: BaseException | None = None
        self._unflushed = 0
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while (task := self._work.get()) is not None:
            if self._error is None:
                try:
                    task()
                except BaseException as exc:  # noqa: BLE001 -- raised by finish()
                    traceback.clear_frames(exc.__traceback__)  # its frames' locals hold the database
                    self._error = exc

    def delete(self, node: ox.NamedNode, path: Path) -> None:
        """Delete the lines of the file ``path`` from graph ``node``, then remove the file."""
        def task() -> None:
            self._unflushed = self._replacement._delete_lines(node, path, self._unflushed)
            path.unlink()
        self._work.put(task)

    def settle_graph(self, node: ox.NamedNode, present: bool) -> None:
        """Once its lines are deleted: drop graph ``node`` if the new version has none, or
        make sure it is there (an empty graph stays a graph)."""
        def task() -> None:
            db = self._replacement.store._db
            if not present:
                db.remove_graph(node)
            elif not db.contains_named_graph(node):
                db.add_graph(node)
        self._work.put(task)

    def finish(self) -> None:
        """Wait for every delete; raise the first error."""
        self.close()
        if self._error is not None:
            raise self._error

    def close(self) -> None:
        if self._thread.is_alive():
            self._work.put(None)
            self._thread.join()


class Tee:
    """The text a load writes into the graphs ``names``, as it goes by: for a replacement to
    compare (files in ``scratch``, see :meth:`~stepnc_graph.store.replacement.Replacement._stage`) and to keep for the next one
    (``kept``, see :mod:`stepnc_graph.store.kept`). Encoded once for both."""

    def __init__(self, names: Sequence[str], scratch: Path | None = None, kept: KeptWriting | None = None) -> None:
        self.paths = {} if scratch is None else {name: scratch / f"new{k}.nt" for k, name in enumerate(names)}
        self.lines = dict.fromkeys(names, 0)
        self._files = {name: open(path, "wb", buffering=1 << 20) for name, path in self.paths.items()}
        self._kept = kept

    def write(self, graph: str, text: str) -> None:
        """N-Triples lines written into ``graph`` (none kept for a graph not in ``names``)."""
        if graph in self.lines and text:
            self.write_bytes(graph, text.encode("utf-8"))

    def write_bytes(self, graph: str, data: bytes) -> None:
        """The same, encoded."""
        if graph not in self.lines or not data:
            return
        if data[-1] != 10:
            data += b"\n"
        self.lines[graph] += data.count(b"\n")
        if (out := self._files.get(graph)) is not None:
            out.write(data)
        if self._kept is not None:
            self._kept.write(graph, data)

    def close(self) -> None:
        for out in self._files.values():
            out.close()

    def keep(self) -> dict[str, KeptText]:
        """The kept texts, once compressed (see :class:`KeptWriting`)."""
        kept, self._kept = self._kept, None
        return {} if kept is None else kept.finish(self.lines)

    def discard(self) -> None:
        """Keep nothing: the load failed, or its text is not the new version."""
        kept, self._kept = self._kept, None
        if kept is not None:
            kept.discard()

    def new_version(self, staged: ox.Store) -> dict[str, Path | None] | None:
        """The files, graph by graph (None: the staged store has no such graph), if each has as
        many lines as the staged store has quads in its graph; else None."""
        found: dict[str, Path | None] = {}
        for name, path in self.paths.items():
            node = ox.NamedNode(name)
            present = staged.contains_named_graph(node)
            if self.lines[name] != (count_in(staged, name) if present else 0):
                return None
            found[name] = path if present else None
        return found


class BlankMatch:
    """Which blank node of the old version of a program graph each one of the new version is.

    A blank node of a program graph is a list cell or a typed value, reached from the
    instance that owns it by one path of properties (``rdf:first``/``rdf:rest`` down a list,
    the attribute at the top): its *place*, named by a digest of the owner's IRI and that
    path. Two nodes of the two versions at the same place are taken for one node, and the new
    version's lines are written with the old label (:meth:`relabel`), so an unchanged list
    compares equal line for line. Nodes without one place of their own are left unmatched and
    are deleted and inserted like changed lines: a member of a SET of lists or typed values
    (several nodes at one place), a node reached twice, or one that nothing reaches. Any
    matching is correct -- what differs is still written -- a good one writes less.
    """

    def __init__(self, old: Path | None, new: Path | None) -> None:
        places = self.places(old)
        self.renamed: dict[bytes, bytes] = {}
        for place, label in self.places(new).items():
            if label is not None and (was := places.get(place)) is not None:
                self.renamed[label] = was
        self.kept = len(self.renamed)

    @staticmethod
    def places(path: Path | None) -> dict[bytes, bytes | None]:
        """place -> label for the blank nodes of an N-Triples file (None: several nodes there)."""
        place: dict[bytes, bytes | None] = {}  # label -> its place (None: it has none)
        parent: dict[bytes, tuple[bytes, bytes]] = {}  # label -> (the blank node above, property)
        props: dict[bytes, bytes] = {}  # one bytes object per property
        for line in file_lines(path):
            if b"_:" not in line or (m := BLANK_OBJECT.search(line)) is None:
                continue
            label = m.group(1)
            subject, prop, _ = line.split(b" ", 2)
            if label in place or label in parent:  # reached twice: no place of its own
                place[label] = None
                parent.pop(label, None)
            elif subject[:2] == b"_:":
                parent[label] = (subject[2:], props.setdefault(prop, prop))
            else:
                place[label] = line_digest(subject + b" " + prop)
        for label in parent:  # down from the nearest node whose place is known, iteratively
            down: list[bytes] = []
            seen: set[bytes] = set()
            node = label
            while node not in place and node in parent and node not in seen:
                down.append(node)
                seen.add(node)
                node = parent[node][0]
            above = place.get(node)  # None: a root without place, or a cycle
            for below in reversed(down):
                above = None if above is None else line_digest(above + b" " + parent[below][1])
                place[below] = above
        found: dict[bytes, bytes | None] = {}
        for label, where in place.items():
            if where is not None:
                found[where] = None if where in found else label
        return found

    def relabel(self, line: bytes) -> bytes:
        """An N-Triples line of the new version with its blank nodes named as in the old one, or
        by a new random label when unmatched: the new version's own labels may be the load's
        (``_:b17``), unique in the load but not in the store."""
        if b"_:" not in line:
            return line
        if line[:2] == b"_:":
            end = line.index(b" ")
            line = b"_:" + self._label(line[2:end]) + line[end:]
        if (m := BLANK_OBJECT.search(line)) is not None:
            line = line[:m.start(1)] + self._label(m.group(1)) + b" .\n"
        return line

    def _label(self, label: bytes) -> bytes:
        was = self.renamed.get(label)
        if was is None:
            was = self.renamed[label] = uuid.uuid4().hex.encode("ascii")
        return was


def append_file(source: Path, out: BinaryIO) -> int:
    """Copy the file ``source`` to ``out``; how many lines it had."""
    lines = 0
    with open(source, "rb") as fh:
        while data := fh.read(1 << 20):
            out.write(data)
            lines += data.count(b"\n")
    return lines


def file_lines(path: Path | None) -> Iterator[bytes]:
    """The lines of an N-Triples file, one at a time (none for None)."""
    if path is None:
        return
    with open(path, "rb") as fh:
        yield from fh


def compared_parts(old: Path | None, new: Path | None, relabel: Callable[[bytes], bytes],
                    scratch: Path) -> Iterator[tuple[Path | None, Iterator[bytes]]]:
    """The old and the new N-Triples file of one graph as pairs of (old lines, new lines
    relabelled) to compare with each other, each pair small enough to hold the old lines in a
    set: the files whole when the old one has at most :data:`~stepnc_graph.store.tuning.COMPARE_BYTES`, else parts of
    both split by a hash of each (relabelled) line, written under ``scratch`` and removed
    once compared. Equal lines fall into the same part."""
    size = old.stat().st_size if old is not None else 0
    parts = -(-size // tuning.COMPARE_BYTES)
    relabelled = (relabel(line) if b"_:" in line else line for line in file_lines(new))  # the test saves a call a line
    if parts <= 1:
        yield old, relabelled
        return
    scratch.mkdir()
    olds = split_lines(file_lines(old), parts, scratch / "old")
    news = split_lines(relabelled, parts, scratch / "new")
    for old_part, new_part in zip(olds, news, strict=True):
        yield old_part, file_lines(new_part)
        old_part.unlink()
        new_part.unlink()


def split_lines(lines: Iterable[bytes], parts: int, stem: Path) -> list[Path]:
    """Write ``lines`` to ``parts`` files named after ``stem``, each line to the file its hash
    chooses (a hash of this process: both versions are split in it)."""
    paths = [stem.with_name(f"{stem.name}{k}.nt") for k in range(parts)]
    files = [open(path, "wb", buffering=1 << 20) for path in paths]
    try:
        for line in lines:
            files[hash(line) % parts].write(line)
    finally:
        for fh in files:
            fh.close()
    return paths


def line_set(path: Path | None) -> set[bytes]:
    """The lines of an N-Triples file as a set (built in C: a quarter of the time that digesting
    them line by line in Python took; the lines of 1.3M quads take about 180 MB)."""
    if path is None:
        return set()
    with open(path, "rb") as fh:
        return set(fh)


def has_blank(line: bytes) -> bool:
    """Whether an N-Triples line (as Oxigraph writes it) has a blank node as subject or object."""
    return b"_:" in line and (line.startswith(b"_:") or BLANK_OBJECT.search(line) is not None)


def line_digest(line: bytes) -> bytes:
    return hashlib.blake2b(line, digest_size=16).digest()


def give_back_freed_memory() -> None:
    """Return the C heap's free memory to the system (glibc's ``malloc_trim``; elsewhere nothing).

    An in-memory Oxigraph store is many small C allocations; once it is dropped, glibc keeps
    the pages for later C allocations, which Python's own small objects never reuse (measured:
    a staged 100k-instance program kept 0.5 GB of the process after it was dropped).
    """
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass
