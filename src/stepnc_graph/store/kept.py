"""The text each graph's last load wrote, kept compressed beside the database (``DIR/kept/``),
so that replacing the graph need not dump its old version from Oxigraph.

A replacement compares the old version of a graph with the new one line by line
(:mod:`stepnc_graph.store.replacement`). Dumped from the store, the old
version costs Oxigraph 5-8 µs of CPU a quad, as it decodes every term: about 120 s of a 1M-instance
program's 13.6M quads, the largest share of such a replacement (measured). The load's own text
gives the same lines -- the mapper writes terms as Oxigraph does -- but for the labels of blank
nodes, which Oxigraph's bulk loader renames. So a load also writes its text here, compressed on a
thread of its own as it goes by (zlib level 1: a 1M-instance program's 1.9 GB of N-Triples take
128 MB and about 3.6 s of CPU, where level 1 of zstd would take 60 MB and 0.9 s but a dependency),
and a replacement reads the old version's lines without blank node from it and only the lines
with one (12 % of a real program's) from the store (:func:`~stepnc_graph.store.kept_graph.graph_from_kept`).

**Never a wrong text.** ``index.json`` names the published generation it describes and, for each
graph, the file of its text and that text's line count. It is written after that generation is
published; a write carries an entry of the index into the next one only when the write left the
graph alone, and only from the index of the generation it started from. So a writer killed
between publishing and writing the index, a rolled-back write, a ``serve --writable`` session or
any other publication leaves an index that names another generation, and nothing is kept: the
next replacement dumps, as it did before. The replacement checks again that the kept lines and
the store's agree in number (a text with a repeated line, say) and that the file decompresses
whole (zlib's checksum), else it dumps.
"""

from __future__ import annotations

import json
import os
import re
import threading
import uuid
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from stepnc_graph.store.handoff import Handoff

INDEX = "index.json"
#: the form of the texts kept: 2 since the loader writes every literal as Oxigraph writes it back
#: (the load time in UTC with ``Z``), so that a text is the store's text and an export may read it
#: (:mod:`stepnc_graph.store.kept_graph`). An entry of another form (1: none named, before) is not
#: read: the graph is dumped, as it was before it kept a text, until its next load
FORM = 2
#: zlib's level (see the module docstring)
LEVEL = 1
#: bytes of decompressed text handled at a time when the kept text is read back
BLOCK = 16 << 20
#: an N-Triples line whose object is a blank node, from the space before it (Oxigraph and the
#: mapper write " .\n" at the end of a line; no label holds a quote, which keeps a literal ending
#: in " _:x" out). The store's test of a line uses it too.
BLANK_OBJECT = re.compile(rb" _:([^ \"\n]+) \.\n$")


@dataclass(frozen=True)
class KeptText:
    """A graph's kept text: its file in the kept directory, its lines and compressed bytes."""

    file: str
    lines: int
    size: int


@dataclass
class OldLines:
    """What :func:`read_without_blank_nodes` found in a kept text."""

    #: lines written out (those without a blank node)
    lines: int = 0
    #: lines with a blank node as subject or object
    blank: int = 0
    #: the predicates of those lines (N-Triples IRIs, ``<...>``)
    predicates: frozenset[bytes] = frozenset()


class KeptTexts:
    """The kept texts of a store (its ``kept/`` directory) and their index."""

    def __init__(self, directory: Path) -> None:
        self.directory = directory

    def valid(self, generation: str | None) -> dict[str, KeptText]:
        """Graph -> kept text, if the index describes ``generation`` (the state of the database
        the caller writes to); else nothing."""
        index = self._index()
        if generation is None or index.get("generation") != generation:
            return {}
        found: dict[str, KeptText] = {}
        for graph, entry in index.get("graphs", {}).items():
            try:
                kept = KeptText(str(entry["file"]), int(entry["lines"]), int(entry["size"]))
            except (KeyError, TypeError, ValueError):
                continue
            if entry.get("form") != FORM:
                continue
            path = self.directory / kept.file
            if path.name == kept.file and path.is_file() and path.stat().st_size == kept.size:
                found[graph] = kept
        return found

    def path(self, kept: KeptText) -> Path:
        return self.directory / kept.file

    def writing(self, names: Sequence[str]) -> "KeptWriting":
        """Start keeping the text of the graphs ``names`` (see :class:`KeptWriting`)."""
        self.directory.mkdir(exist_ok=True)
        return KeptWriting(self.directory, names)

    def publish(self, generation: str, since: str | None, written: dict[str, KeptText],
                touched: set[str] | None) -> None:
        """Describe the just published ``generation``, written from generation ``since``: the
        texts ``written`` by the write, and the entries of ``since``'s index for the graphs it
        did not touch (``touched`` None: it may have touched any). Files no entry names go."""
        index = self._index()
        carried = {} if touched is None or index.get("generation") != since or since is None else {
            graph: entry for graph, entry in index.get("graphs", {}).items() if graph not in touched}
        graphs = {**carried, **{g: {"file": k.file, "lines": k.lines, "size": k.size, "form": FORM} for g, k in written.items()}}
        if graphs or self.directory.exists():
            self.directory.mkdir(exist_ok=True)
            tmp = self.directory / (INDEX + ".tmp")
            tmp.write_text(json.dumps({"generation": generation, "graphs": graphs}, sort_keys=True) + "\n")
            os.replace(tmp, self.directory / INDEX)
        self.collect()

    def collect(self) -> None:
        """Delete the files the index does not name (from superseded or rolled-back writes)."""
        if not self.directory.is_dir():
            return
        named = {str(e.get("file")) for e in self._index().get("graphs", {}).values() if isinstance(e, dict)}
        for entry in self.directory.iterdir():
            if entry.name != INDEX and entry.name not in named:
                entry.unlink(missing_ok=True)

    def _index(self) -> dict:  # type: ignore[type-arg]
        try:
            index = json.loads((self.directory / INDEX).read_text())
        except (OSError, ValueError):
            return {}
        return index if isinstance(index, dict) else {}


class KeptWriting:
    """Texts being kept, one file per graph, compressed on a thread of its own (zlib lets go of
    the interpreter while it compresses, so the load's producer goes on beside it)."""

    def __init__(self, directory: Path, names: Sequence[str]) -> None:
        self._paths = {name: directory / f"{uuid.uuid4().hex}.nt.z" for name in names}
        self._work: Handoff[tuple[str, bytes]] = Handoff(2)  # it keeps up
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def write(self, graph: str, data: bytes) -> None:
        """N-Triples lines of ``graph`` (ignored for a graph not kept)."""
        if graph in self._paths and data:
            self._work.put((graph, data))

    def _run(self) -> None:
        files: dict[str, tuple[BinaryIO, zlib._Compress]] = {}
        try:
            while (item := self._work.get()) is not None:  # None: closed by _stop, or aborted
                graph, data = item
                if graph not in files:
                    files[graph] = (open(self._paths[graph], "wb"), zlib.compressobj(LEVEL))
                out, compressor = files[graph]
                out.write(compressor.compress(data))
            for out, compressor in files.values():
                out.write(compressor.flush())
        except BaseException as exc:  # noqa: BLE001 -- finish() then keeps nothing
            self._error = exc
            self._work.abort()  # the producer's writes return at once (a full disk, say)
        finally:
            for out, _ in files.values():
                try:
                    out.close()  # writes what is buffered: a full disk fails here too
                except OSError as exc:
                    self._error = self._error or exc

    def finish(self, lines: dict[str, int]) -> dict[str, KeptText]:
        """Wait for the compression; the kept texts of the graphs that got lines (``lines``: how
        many each, as the caller counted them); none when it failed (a full disk, say): keeping
        is worth a faster replacement, never a failed load."""
        self._stop()
        if self._error is not None:
            self.discard()
            return {}
        return {name: KeptText(path.name, lines[name], path.stat().st_size)
                for name, path in self._paths.items() if path.exists()}

    def discard(self) -> None:
        """Stop and delete what was written (a failed or untrusted load)."""
        self._stop()
        for path in self._paths.values():
            path.unlink(missing_ok=True)

    def _stop(self) -> None:
        self._work.close()
        self._thread.join()


def read_without_blank_nodes(path: Path, out: BinaryIO) -> OldLines:
    """Write the lines of the kept text ``path`` that have no blank node to ``out``; count them
    and the others, and name the others' predicates (to read those lines from the store).
    Raises ``zlib.error`` or ``EOFError`` when the file is damaged or cut short.

    A Python loop over the occurrences of ``_:`` (1.4M in a real 1M-instance program: 2.4 s for
    its 1.2 GB; a regular expression over the lines took 15 s)."""
    found = OldLines()
    predicates: set[bytes] = set()
    for block in blocks(path):
        found.lines += block.count(b"\n")
        find, run = block.find, 0
        pos = 0
        while (i := find(b"_:", pos)) >= 0:
            start = block.rfind(b"\n", 0, i) + 1
            end = find(b"\n", i) + 1
            if start == i or BLANK_OBJECT.fullmatch(block, i - 1, end):
                out.write(block[run:start])
                run = end
                found.blank += 1
                predicates.add(block[start:end].split(b" ", 2)[1])
            pos = end
        out.write(block[run:])
    found.lines -= found.blank
    found.predicates = frozenset(predicates)
    return found


def blocks(path: Path) -> Iterator[bytes]:
    """The decompressed text of ``path`` in blocks of whole lines of about :data:`BLOCK` bytes."""
    decompressor = zlib.decompressobj()
    rest = b""
    with open(path, "rb") as fh:
        while data := fh.read(1 << 20):
            rest += decompressor.decompress(data)
            if len(rest) >= BLOCK:
                cut = rest.rfind(b"\n") + 1
                yield rest[:cut]
                rest = rest[cut:]
        rest += decompressor.flush()
    if not decompressor.eof:
        raise EOFError(f"{path}: the kept text is cut short")
    if rest:
        if not rest.endswith(b"\n"):
            raise EOFError(f"{path}: the kept text ends inside a line")
        yield rest
