"""The vocabulary graph every store holds (the analysis terms it adds: :mod:`stepnc_graph.vocabulary.analysis`).

SPARQL engines do not read ontologies they are not given: ``?c
rdfs:subClassOf* stepnc:turning_machine_tool_body`` finds nothing unless the
subclass axioms are in the store. So the loader keeps the whole generated
vocabulary (``ontology/*.ttl``: the ISO classes, attribute properties and
enumeration items, the ``p21:`` terms, the generic ``attr:`` properties and
the ``sga:`` analysis terms) in one named graph, :data:`VOCABULARY_GRAPH`,
with the SHA-256 of those files recorded in it (``sga:vocabularyDigest``).
A load rewrites the graph when it is missing or its digest differs from the
shipped files, inside the same atomic load as the file. Exports of one file
never include it (the writer reads the file's graph only).

The analysis vocabulary's definitions live below the generators that write it, in
:mod:`stepnc_graph.vocabulary.analysis`.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.core.naming import ANALYSIS_NS, VOCABULARY_GRAPH
from stepnc_graph.core.resources import ontology_dir

if TYPE_CHECKING:
    from stepnc_graph.store import Store

DIGEST = ANALYSIS_NS + "vocabularyDigest"


def vocabulary_files(directory: Path | None = None) -> tuple[Path, ...]:
    """The Turtle files the vocabulary graph holds: every ``ontology/*.ttl``, sorted."""
    return tuple(sorted((directory or ontology_dir()).glob("*.ttl")))


def digest(files: tuple[Path, ...]) -> str:
    """SHA-256 over the files' names and bytes (a change to any file makes the graph stale)."""
    h = hashlib.sha256()
    for path in files:
        h.update(path.name.encode("utf-8") + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


@lru_cache(maxsize=4)
def _digest(files: tuple[Path, ...], stamps: tuple[float, ...]) -> str:
    del stamps  # part of the cache key only: a rewritten file is read again
    return digest(files)


def vocabulary_digest(directory: Path | None = None) -> str:
    """The digest of the shipped ontology files (cached per file state)."""
    files = vocabulary_files(directory)
    return _digest(files, tuple(p.stat().st_mtime for p in files))


def stored_digest(store: Store) -> str | None:
    """The digest recorded in the store's vocabulary graph; None if there is no such graph."""
    rows = store.query(f"SELECT ?d WHERE {{ GRAPH <{VOCABULARY_GRAPH}> {{ <{VOCABULARY_GRAPH}> <{DIGEST}> ?d }} }}")
    for row in rows:
        return row[0].value if isinstance(row[0], ox.Literal) else None
    return None


def vocabulary_status(store: Store, directory: Path | None = None) -> str:
    """``current``, ``stale`` (written from other ontology files) or ``missing``."""
    found = stored_digest(store)
    if found is None:
        return "missing"
    return "current" if found == vocabulary_digest(directory) else "stale"


def ensure_vocabulary(store: Store, directory: Path | None = None,
                      target: Callable[[str], str] | None = None) -> bool:
    """Write the vocabulary graph when it is missing or stale; True if it was written.

    Called by the loader inside a file's atomic load (``before_commit``), so
    on disk the rewrite is covered by the load's checkpoint; ``target`` (the load's) names the
    graph to write instead, which a remote store stages and swaps in with the program.
    """
    value = vocabulary_digest(directory)
    if stored_digest(store) == value:
        return False
    where = target(VOCABULARY_GRAPH) if target is not None else VOCABULARY_GRAPH
    store.update(f"DROP SILENT GRAPH <{where}>")
    store.add_turtle(where, vocabulary_turtle(directory))
    return True


def vocabulary_turtle(directory: Path | None = None) -> str:
    """The vocabulary graph's content as one Turtle document: the ontology files one after the
    other (Turtle allows prefix declarations anywhere; the files use no blank node labels and no
    base, so nothing in one can change the meaning of another) and the digest.

    One text for the store to parse, rather than a Python object per triple: this is most of
    what a throw-away store pays before its first query.
    """
    texts = [path.read_text(encoding="utf-8") for path in vocabulary_files(directory)]
    digest_line = f"<{VOCABULARY_GRAPH}> <{DIGEST}> {ox.Literal(vocabulary_digest(directory))} .\n"
    return "\n".join([*texts, digest_line])


def vocabulary_for_queries(store: Store) -> None:
    """Give a throw-away (in-memory) store the vocabulary graph before queries read it: loads into
    such a store skip it, as most throw-away stores are never queried (load --memory, validate)."""
    if is_throwaway(store):
        ensure_vocabulary(store)


def is_throwaway(store: Store) -> bool:
    """An in-memory store: the loader leaves the vocabulary graph out of it (see above)."""
    return not store.capabilities.persistent
