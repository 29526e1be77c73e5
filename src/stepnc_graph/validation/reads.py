"""What the checks may read, worked out from their SPARQL text: whether the position triples
(``p21:id``, ``p21:line``) and which attributes must be in the throw-away graph ``validate FILE``
checks (:mod:`.throwaway`). Pattern matching over every check (some 50 ms for the shipped ones),
so the build works it out once for the shipped checks and stores the answer beside them
(:mod:`.compiled`); other shapes get it worked out on first use, once per process."""

from __future__ import annotations

import re
from collections.abc import Sequence

from stepnc_graph.validation.engine import Check

#: ``p21:id`` or ``p21:line`` in a query, as a full IRI or prefixed (any prefix: erring on the side of keeping them)
_POSITION_TERM = re.compile(r"(?:p21#|:)(?:id|line)\b")


def reads_positions(checks: Sequence[Check]) -> bool:
    """Whether a check (an organisation's own SPARQL, say) may read ``p21:id``/``p21:line``: it
    names them, reads any predicate (a variable in predicate position), or is ``sh:closed``. Then
    the throw-away graph keeps those triples; otherwise their lines come from the load (a sixth
    fewer triples to insert; 100k instances, end to end, medians in one quiet hour: 4.2 s with
    them, 3.5-3.8 s without)."""
    return any(_POSITION_TERM.search(c.query) or c.constraint == "closed"
               or (c.sparql_node is not None and _ANY_PREDICATE.search(_PROJECTION.sub("SELECT ", c.query)))
               for c in checks)


#: a triple pattern whose predicate is a variable: a variable after a subject (a variable, an IRI,
#: a blank node's label, the end of a ``[...]``) and before an object (any term); after a ``)`` (a
#: collection, or a FILTER's end before a pattern) only before a variable or a literal. Broad on
#: purpose: a false match (``GROUP BY ?a ?b ?c``) only keeps every triple in the graph
_ANY_PREDICATE = re.compile(r"(?:[?$]\w+|<[^>\s]*>|_:\w+|\])\s+[?$]\w+\s+[^\s.;,}]"
                            r"|\)\s+[?$]\w+\s+(?!a\s)[^\s.;,}<]")
#: a SELECT's projection (``SELECT DISTINCT ?this ?item ?dim``: three variables, no triple pattern)
_PROJECTION = re.compile(r"\bSELECT\b[^{]*?(?=\bWHERE\b|\{)", re.IGNORECASE)


def properties_read(checks: Sequence[Check]) -> frozenset[str] | None:
    """The properties (bare IRIs) that the checks which may run on a graph the Part 21 mapping
    wrote can read: every IRI their queries name (:mod:`.implied`: the checks it guarantees run
    only when the graph lacks the guarantee, and the load then writes every attribute). None when
    a check may read a property it does not name: a variable or negated predicate, ``sh:closed``,
    prefixed names or a base IRI. The throw-away graph then leaves the other attributes out (a
    quarter of a replicated real program's triples: placement names, its_ids, coordinates)."""
    found: set[str] = set()
    for c in checks:
        if c.implied is not None:  # run only when the graph lacks the guarantee: then it holds everything
            continue
        text = " ".join([c.query, c.path or "", c.multiplicity or "", *c.other_targets])
        if c.constraint == "closed" or _UNNAMED.search(text) or _ANY_PREDICATE.search(_PROJECTION.sub("SELECT ", text)):
            return None
        found.update(_IRI.findall(text))
    return frozenset(found)


#: an IRI in a query
_IRI = re.compile(r"<([^<>\s]*)>")
#: what lets a query read a property it does not write out: a negated property set (``!<p>``,
#: ``!^<p>``, ``!a``, ``!(...)`` of those), a PREFIX or BASE declaration, a predicate after ``;``
_UNNAMED = re.compile(r"!\s*(?:\(\s*)?(?:<|\^|a\b)|\b(?:PREFIX|BASE)\b|;\s*[?$]\w+\s", re.IGNORECASE)
