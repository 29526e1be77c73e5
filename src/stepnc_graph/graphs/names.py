"""Graphs named the short way: ``--graph shaft.stp`` for ``https://w3id.org/stepnc-graph/data/shaft.stp``.

Graph IRIs are long and the store rarely holds two programs of one file name, so a command that
takes a graph takes its full IRI, the end of it at a ``/`` (a file name, ``data/shaft.stp``,
``shaft.stp/links/plm.csv``) or a file name without its extension -- when exactly one of the
store's graphs ends so. A name that matches none, or several, is an error that lists the graphs
it could mean: a silent guess could remove or export the wrong program.
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence
from urllib.parse import unquote

from stepnc_graph.core.errors import StepncGraphError


class UnknownGraph(StepncGraphError, ValueError):
    """A graph name that names no graph of the store, or several."""


def _ends(graph: str, given: str) -> bool:
    return any(g == given or g.endswith("/" + given.lstrip("/")) for g in (graph, unquote(graph)))


def _stem(graph: str) -> str:
    last = unquote(graph.rstrip("/").rsplit("/", 1)[-1])
    return last.rsplit(".", 1)[0] if "." in last else last


def resolve_graph(given: str, graphs: Sequence[str]) -> str:
    """The one graph of ``graphs`` that ``given`` names (see the module); :class:`UnknownGraph`
    naming the candidates otherwise."""
    if given in graphs:
        return given
    for matches in (sorted(g for g in graphs if _ends(g, given)), sorted(g for g in graphs if _stem(g) == given)):
        if len(matches) == 1:
            return matches[0]
        if matches:
            raise UnknownGraph(f"{given!r} names {len(matches)} graphs: {', '.join(matches)}; give more of the IRI")
    raise UnknownGraph(f"no graph {given} in the store" + _suggest(given, graphs))


def _suggest(given: str, graphs: Sequence[str]) -> str:
    """"; did you mean ..." by file name, or the graphs there are when they are few."""
    if not graphs:
        return " (it holds none)"
    names = {unquote(g.rstrip("/").rsplit("/", 1)[-1]): g for g in graphs}
    wanted = unquote(given.rstrip("/").rsplit("/", 1)[-1])
    close = [names[n] for n in difflib.get_close_matches(wanted, list(names), n=3, cutoff=0.6)]
    if close:
        return f"; did you mean {' or '.join(close)}?"
    if len(graphs) <= 5:
        return f"; it holds {', '.join(sorted(graphs))}"
    return "; `stepnc-graph info` lists them"
