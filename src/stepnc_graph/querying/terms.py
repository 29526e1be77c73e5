"""Warnings about the project's terms a query names: a mistyped term answers nothing, silently.

SPARQL has no notion of an unknown IRI: ``?ws a stepnc:workingstepp`` is a valid query with no
rows. So before a user's query runs, the ``stepnc:``, ``attr:`` and ``sga:`` terms it names (by a
predeclared or declared prefix, or written out in full) are looked up in the store's vocabulary
graph: a term the vocabulary does not have gets a warning with the closest terms it does have.
A generic ``attr:`` property the vocabulary has but the queried data never uses gets one too --
the derived layer writes generic values for the process entities only (``attr:theoretical_size``
of a tolerance is never written), so the warning names the per-entity properties that hold them.

The look-ups are index look-ups on the terms named (a query names a handful); only a miss reads
the vocabulary's names for "did you mean".
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

import pyoxigraph as ox

from stepnc_graph.core.naming import ANALYSIS_NS, ATTRIBUTE_NS, STEPNC_NS, VOCABULARY_GRAPH

if TYPE_CHECKING:
    from stepnc_graph.store import Store

#: The namespaces whose terms are checked, with the prefix a message writes them with.
CHECKED = {STEPNC_NS: "stepnc", ATTRIBUTE_NS: "attr", ANALYSIS_NS: "sga"}

#: Strings and comments (skipped), IRIs, PREFIX declarations and prefixed names of a SPARQL text.
_TOKEN = re.compile(
    r'(?P<skip>"""(?:[^"\\]|\\.|"(?!""))*"""|\'\'\'(?:[^\'\\]|\\.|\'(?!\'\'))*\'\'\''
    r'|"(?:[^"\\\n]|\\.)*"|\'(?:[^\'\\\n]|\\.)*\'|#[^\n]*)'
    r'|(?P<prefix>PREFIX\s+(?P<declared>[A-Za-z][\w.-]*)?:\s*<(?P<namespace>[^<>"\s]*)>)'
    r'|<(?P<iri>[^<>"{}|^`\\\s]*)>'
    r'|(?<![\w?$:])(?P<pname>[A-Za-z][\w.-]*)?:(?P<local>[\w][\w.-]*)',
    re.IGNORECASE)


def named_terms(text: str, prefixes: Mapping[str, str]) -> list[str]:
    """The IRIs of the checked namespaces ``text`` names, in order of first use, once each.
    ``prefixes`` are those predeclared; the query's own PREFIX declarations override them."""
    known = dict(prefixes)
    found: dict[str, None] = {}
    for m in _TOKEN.finditer(text):
        if m.group("skip"):
            continue
        if m.group("prefix"):
            known[m.group("declared") or ""] = m.group("namespace")
            continue
        iri = m.group("iri")
        if iri is None:
            namespace = known.get(m.group("pname") or "")
            iri = None if namespace is None else namespace + m.group("local").rstrip(".")
        if iri is not None and _namespace(iri) is not None:
            found.setdefault(iri)
    return list(found)


def _namespace(iri: str) -> str | None:
    return next((ns for ns in CHECKED if iri.startswith(ns) and len(iri) > len(ns)), None)


def show(iri: str) -> str:
    """``stepnc:x`` for a term of a checked namespace."""
    ns = _namespace(iri)
    return f"{CHECKED[ns]}:{iri[len(ns):]}" if ns else f"<{iri}>"


def _values(iris: Iterable[str]) -> str:
    return " ".join(f"<{i}>" for i in iris)


def _vocabulary_has(store: Store, terms: list[str]) -> set[str]:
    rows = store.query(f"SELECT DISTINCT ?t WHERE {{ VALUES ?t {{ {_values(terms)} }} "
                       f"GRAPH <{VOCABULARY_GRAPH}> {{ ?t ?p ?o }} }}")
    return {row[0].value for row in rows}


def _vocabulary_names(store: Store) -> list[str]:
    """Every term of the checked namespaces the vocabulary graph describes (for suggestions)."""
    tests = " || ".join(f'STRSTARTS(STR(?t), "{ns}")' for ns in CHECKED)
    rows = store.query(f"SELECT DISTINCT ?t WHERE {{ GRAPH <{VOCABULARY_GRAPH}> {{ ?t a ?k }} FILTER({tests}) }}")
    return [row[0].value for row in rows]


def suggest(term: str, names: list[str]) -> list[str]:
    """The vocabulary's terms closest to ``term``, by their local names (any checked namespace:
    ``stepnc:its_id`` is meant as ``attr:its_id``), case ignored."""
    by_name: dict[str, list[str]] = {}
    for n in names:
        by_name.setdefault(show(n).split(":", 1)[1].lower(), []).append(n)
    wanted = show(term).split(":", 1)[1].lower()
    close = difflib.get_close_matches(wanted, list(by_name), n=3, cutoff=0.75)
    return [show(n) for name in close for n in sorted(by_name[name], key=show)][:4]


def _unused_generic(store: Store, term: str, dataset: Mapping[str, Any]) -> str | None:
    """A warning for the generic property ``term`` when no triple of the queried data uses it."""
    if not term.startswith(ATTRIBUTE_NS) or store.query(f"ASK {{ ?s <{term}> ?o }}", **dataset):
        return None
    from stepnc_graph.loading.derive import iso14649_rules

    rows = store.query(f"SELECT DISTINCT ?p WHERE {{ GRAPH <{VOCABULARY_GRAPH}> {{ "
                       f"{{ ?p <http://www.w3.org/2000/01/rdf-schema#subPropertyOf> <{term}> }} UNION "
                       f"{{ <{term}> <http://www.w3.org/2000/01/rdf-schema#seeAlso> ?kind . "
                       f"?p <http://www.w3.org/2000/01/rdf-schema#subPropertyOf> ?kind }} }} }}")
    per_entity = sorted(show(row[0].value) for row in rows if isinstance(row[0], ox.NamedNode))
    listed = ", ".join(per_entity[:4]) + (f" and {len(per_entity) - 4} more" if len(per_entity) > 4 else "")
    if term in set(iso14649_rules().generic.values()):
        return f"no queried program has a value for {show(term)}" + (f" ({listed})" if listed else "")
    return (f"{show(term)} is never written: the derived layer gives generic values to the process entities "
            f"only, not to ISO 10303 resources, toolpaths, tolerances or parameters (docs/querying.md); "
            f"query {listed or 'the per-entity properties'} instead")


_GRAPH = re.compile(r"\bGRAPH\s*<([^<>\s]*)>", re.IGNORECASE)


def graph_warnings(text: str, dataset: Mapping[str, Any]) -> list[str]:
    """``GRAPH <iri>`` for a graph the query's named graphs do not hold matches nothing: the
    vocabulary graph and the derived layers are part of the default graph, not named graphs."""
    named = {g.value for g in dataset.get("named_graphs", ())}
    if "named_graphs" not in dataset:
        return []
    out = []
    for iri in dict.fromkeys(_GRAPH.findall(_strip(text))):
        if iri not in named:
            what = "the vocabulary graph" if iri == VOCABULARY_GRAPH else "this graph"
            out.append(f"GRAPH <{iri}> matches nothing: {what} is not one of the query's named graphs (the loaded "
                       "programs and link graphs); the vocabulary and the derived layers are in the default graph, "
                       "so leave out the GRAPH")
    return out


def _strip(text: str) -> str:
    """``text`` without its strings and comments."""
    return "".join(m.group() if not m.group("skip") else " " for m in re.finditer(rf"{_TOKEN.pattern}|[\s\S]", text,
                                                                                   re.IGNORECASE))


def term_warnings(store: Store, text: str, prefixes: Mapping[str, str], dataset: Mapping[str, Any]) -> list[str]:
    """Warnings for the ``stepnc:``/``attr:``/``sga:`` terms of the query ``text`` that the store's
    vocabulary graph does not have ("did you mean"), generic properties the queried data never
    uses, and GRAPH patterns naming a graph outside the dataset. Nothing about terms when the store
    has no vocabulary graph to look in."""
    graphs = graph_warnings(text, dataset)
    terms = named_terms(text, prefixes)
    if not terms or not store.has_graph(VOCABULARY_GRAPH):
        return graphs
    has = _vocabulary_has(store, terms)
    out: list[str] = graphs
    names: list[str] | None = None
    for term in terms:
        if term in has:
            if (unused := _unused_generic(store, term, dataset)) is not None:
                out.append(unused)
            continue
        names = _vocabulary_names(store) if names is None else names
        close = suggest(term, names)
        out.append(f"{show(term)} is not in the vocabulary (it matches nothing)"
                   + (f"; did you mean {' or '.join(close)}?" if close else ""))
    return out
