"""What a load reads and which graph each input becomes: files, directories, standard input.

Graph IRIs never collide silently. Within one load, two inputs that would
become the same graph are refused before anything is written; across loads, a
graph that holds another file (by its absolute path) is only replaced when
asked (``replace=True``). Files found under a directory are named by their path
relative to it, so ``a/x.stp`` and ``b/x.stp`` of one directory load side by side.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from urllib.parse import quote

import pyoxigraph as ox

from stepnc_graph.core.formats import input_suffixes, reads_as
from stepnc_graph.core.naming import DATA_BASE, instance_prefix
from stepnc_graph.loading.common import Source, SourceError, check_iri
from stepnc_graph.store import Store

__all__ = ["STDIN", "STDIN_GRAPH", "SUFFIXES", "Source", "SourceError", "check_iri", "plan_sources", "refuse_replacing_other_files"]

#: file name endings of Part 21 programs, and of program graphs in JSON-LD, compared case-insensitively
SUFFIXES = input_suffixes()
STDIN = "-"

#: the graph of a program read from standard input into a throw-away store (query, plan, validate),
#: where no --base-iri is asked for: the store is gone when the command ends
STDIN_GRAPH = DATA_BASE + "stdin"


def _relative_name(relative: Path) -> str:
    return "/".join(quote(part, safe="") for part in relative.parts)


def plan_sources(inputs: Sequence[str | Path], base_iri: str | None = None,
                 stdin_graph: str | None = None) -> list[Source]:
    """The files to load and their graph IRIs, in order.

    A directory stands for every Part 21 file under it (``.stp``, ``.step``,
    ``.p21``, any case) and every JSON-LD program graph (``.jsonld``), sorted.
    Graph IRIs: ``base_iri`` for a single file,
    else ``base_iri`` (or ``https://w3id.org/stepnc-graph/data/``) as a prefix of
    the file name -- of the path relative to its directory, for a file found in
    one; a JSON-LD file names its own graph, used unless ``base_iri`` is given.
    ``-`` is standard input and needs ``base_iri``, or ``stdin_graph`` (a throw-away store's
    name for it, :data:`STDIN_GRAPH`).
    """
    if base_iri is not None:
        check_iri(base_iri, "--base-iri")
    if sum(str(item) == STDIN for item in inputs) > 1:
        raise SourceError("standard input (-) is given twice: it can be read once")
    expanded: list[tuple[str, Path | None, str]] = []  # (name, path, name within the graph prefix)
    for item in inputs:
        if str(item) == STDIN:
            expanded.append(("<stdin>", None, "stdin"))
            continue
        p = Path(item)
        if p.is_dir():
            found = sorted(f for f in p.rglob("*") if f.suffix.lower() in SUFFIXES and f.is_file())
            if not found:
                raise SourceError(f"{p}: no Part 21 or JSON-LD files ({', '.join(SUFFIXES)}) in this directory")
            expanded.extend((str(f), f, _relative_name(f.relative_to(p))) for f in found)
        else:
            expanded.append((str(p), p, quote(p.name, safe="")))
    single = len(expanded) == 1 and not any(Path(str(i)).is_dir() for i in inputs if str(i) != STDIN)
    sources = []
    for name, path, local in expanded:
        if path is None and base_iri is None and stdin_graph is not None:
            sources.append(Source(name, path, stdin_graph))
            continue
        if path is None and base_iri is None:
            raise SourceError("standard input (-) has no file name: give its graph IRI with --base-iri")
        if single and base_iri is not None:
            graph = base_iri
        else:
            graph = (instance_prefix(base_iri) if base_iri is not None else DATA_BASE) + local
        if path is not None and base_iri is None and reads_as(path, "jsonld"):
            from stepnc_graph.loading.jsonld import named_graph_of  # a JSON-LD document names its graph

            graph = named_graph_of(path) or graph
        sources.append(Source(name, path, graph))
    _refuse_repeats(sources)
    return sources


def _refuse_repeats(sources: list[Source]) -> None:
    by_graph: dict[str, list[Source]] = defaultdict(list)
    for s in sources:
        by_graph[s.graph].append(s)
    clashes = {g: group for g, group in by_graph.items() if len({s.identity for s in group}) > 1}
    if clashes:
        graph, group = next(iter(clashes.items()))
        raise SourceError(f"{' and '.join(s.name for s in group)} would both be loaded as graph <{graph}>; "
                          "load their directory (graphs are then named by relative path) or give each its own "
                          "--base-iri")


def refuse_replacing_other_files(store: Store, sources: Sequence[Source]) -> None:
    """:class:`SourceError` when a graph of ``sources`` already holds a different file."""
    for s in sources:
        if not store.has_graph(s.graph):
            continue
        rows = store.query(f"SELECT ?src WHERE {{ GRAPH {ox.NamedNode(s.graph)} {{ "
                           f"{ox.NamedNode(s.graph)} <http://purl.org/dc/terms/source> ?src }} }}")
        held = [str(row[0].value) for row in rows]
        if held and s.identity not in held:
            raise SourceError(f"graph <{s.graph}> already holds {held[0]}, not {s.identity}; pass --replace to "
                              "replace it, or --base-iri to load beside it")
