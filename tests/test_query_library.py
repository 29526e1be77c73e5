"""The shape of the library queries: no join written as a FILTER on two variables.

``{ SELECT ?t ... GROUP BY ?t } ?tool_node a stepnc:machining_tool . FILTER(?tool_node = ?t)``
asks Oxigraph (and rdflib) for the cartesian product of the two parts, filtered afterwards: no
join key is shared, so the cost grows with the product of their sizes. On a store of three
replicated real programs of 100k instances (2,248 tools and setups each) ``tool-usage`` and
``workingsteps-per-setup`` written that way did not finish within 60 s; joined on a shared variable
they take about a second (docs/querying.md, "Speed"). The same FILTER in an ``OPTIONAL`` (its
left-join condition) is no better. So no library query may hold, in positive form, an equality
of two variables -- ``?a = ?b`` or ``sameTerm(?a, ?b)``, alone or as a conjunct of ``&&`` -- in a
FILTER or an OPTIONAL's condition: write one variable in both places instead. Negated forms
(``?a != ?b``, ``!sameTerm(?a, ?b)``) are comparisons, not joins, and stay allowed.

The check reads the SPARQL algebra (rdflib's parser), not the text, so layout and comments do
not matter. It is timed nowhere: the quadratic plans are a property of the query's shape.
"""

from __future__ import annotations

from typing import Any

import pytest
from rdflib.plugins.sparql import prepareQuery
from rdflib.plugins.sparql.parserutils import CompValue
from rdflib.term import Variable

from stepnc_graph.querying.query import library

PREFIXES = """PREFIX stepnc: <https://w3id.org/stepnc-graph/iso14649#>
PREFIX attr: <https://w3id.org/stepnc-graph/attribute#>
PREFIX sga: <https://w3id.org/stepnc-graph/analysis#>
PREFIX p21: <https://w3id.org/stepnc-graph/p21#>
"""


def _conjuncts(expr: Any) -> list[Any]:
    """The parts of a conjunction (``a && b && c``); any other expression is its own only part."""
    if isinstance(expr, CompValue) and expr.name == "ConditionalAndExpression":
        return [p for part in [expr["expr"], *(expr.get("other") or [])] for p in _conjuncts(part)]
    return [expr]


def _variable_equality(expr: Any) -> tuple[str, str] | None:
    """``(a, b)`` when ``expr`` is ``?a = ?b`` or ``sameTerm(?a, ?b)``, else None."""
    if not isinstance(expr, CompValue):
        return None
    if expr.name == "RelationalExpression" and expr.get("op") == "=":
        left, right = expr.get("expr"), expr.get("other")
    elif expr.name == "Builtin_sameTerm":
        left, right = expr.get("arg1"), expr.get("arg2")
    else:
        return None
    if isinstance(left, Variable) and isinstance(right, Variable):
        return str(left), str(right)
    return None


def equality_joins(text: str) -> list[tuple[str, str]]:
    """Every pair of variables a FILTER (or an OPTIONAL's condition) of ``text`` requires to be equal."""
    found: list[tuple[str, str]] = []

    def walk(node: Any) -> None:
        if isinstance(node, CompValue):
            if node.name in ("Filter", "LeftJoin") and node.get("expr") is not None:
                for part in _conjuncts(node["expr"]):
                    pair = _variable_equality(part)
                    if pair:
                        found.append(pair)
            for value in node.values():
                walk(value)
        elif isinstance(node, (list, tuple)):
            for value in node:
                walk(value)

    walk(prepareQuery(text).algebra)
    return found


# -- the check finds what it must, and only that ---------------------------------------------------


@pytest.mark.parametrize(("where", "pairs"), [
    # the shape tool-usage and workingsteps-per-setup had: an aggregate joined by a FILTER
    ("{ SELECT ?t (COUNT(?step) AS ?n) WHERE { ?step sga:tool ?t } GROUP BY ?t } "
     "?tool_node a stepnc:machining_tool . FILTER(?tool_node = ?t)", [("tool_node", "t")]),
    ("?a sga:tool ?t . ?b a stepnc:setup FILTER(sameTerm(?a, ?b))", [("a", "b")]),
    # inside an OPTIONAL the FILTER is the left join's condition (holes-and-drilling had it)
    ("?f a stepnc:round_hole OPTIONAL { ?h a stepnc:round_hole . ?ws sga:feature ?h FILTER(?h = ?f) }",
     [("h", "f")]),
    # a conjunct of && (knurls-and-tools had two per OPTIONAL); FILTER(a) FILTER(b) is a conjunction too
    ("?f a stepnc:knurl OPTIONAL { ?k2 a stepnc:knurl . ?ws sga:feature ?k2 ; attr:its_operation ?op2 "
     "FILTER(?k2 = ?f && (?op2 = ?op)) }", [("k2", "f"), ("op2", "op")]),
    ("?a sga:tool ?t . ?b sga:tool ?u FILTER(?a = ?b) FILTER(BOUND(?t))", [("a", "b")]),
    # comparisons that are no joins: negated, against a constant, inside an OR, in a BIND
    ("?s sga:tool ?t ; sga:toolBefore ?b FILTER(!sameTerm(?t, ?b))", []),
    ("?s sga:tool ?t ; sga:toolBefore ?b FILTER(?t != ?b && !(?s = ?b))", []),
    ("?s sga:order ?o FILTER(?o = 3 || ?s = <urn:x>)", []),
    ("?s sga:order ?o ; sga:next ?n . ?n sga:order ?p FILTER(?o < ?p || ?o = ?p)", []),
    ("?s sga:tool ?t ; sga:toolBefore ?b BIND(IF(?t = ?b, 0, 1) AS ?change)", []),
])
def test_the_check_finds_equality_joins(where: str, pairs: list[tuple[str, str]]) -> None:
    assert equality_joins(f"{PREFIXES}SELECT * WHERE {{ {where} }}") == pairs


# -- the library -------------------------------------------------------------------------------------


@pytest.mark.parametrize("query", library(), ids=lambda q: q.name)
def test_no_library_query_joins_by_a_filter(query: Any) -> None:
    assert equality_joins(query.text) == [], (
        f"{query.name}: a FILTER equates two variables, a cartesian product filtered afterwards "
        "(quadratic on a store of several programs); write one shared variable instead")
