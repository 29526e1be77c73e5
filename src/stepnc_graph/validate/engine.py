"""SHACL compiled to SPARQL and run by the embedded Oxigraph store.

Why not a SHACL library: pySHACL needs an rdflib copy of the data (about 28 s
of parsing alone for 100k instances) and its SPARQL-based constraints run one
query per focus node; measured in ``bench/validate_bench.py``. Here every
constraint of every shape becomes **one** SELECT over the whole program graph,
Oxigraph evaluates it in Rust on the data already in the store, and only the
shapes whose target classes occur in the graph run. pySHACL stays the
reference: the tests run it on the same shapes and data and require the same
results.

How the SHACL semantics is kept:

* the class hierarchy (``shapes/support.ttl`` and any rdfs:subClassOf in the
  shapes files) is part of the data graph in SHACL's sense; it is compiled into
  the queries (``VALUES`` of the subclasses of a target or ``sh:class``), so it
  is never written into the store;
* a constraint that applies to value nodes is a FILTER on each value; nested
  shapes (``sh:node``, ``sh:not``, ``sh:or``, ``sh:and``, ``sh:xone``) compile to
  boolean SPARQL expressions ("the node conforms");
* SHACL-SPARQL constraints run with ``$this`` bound by the target pattern (the
  pre-binding of SHACL 5.3.1, for queries without sub-SELECTs, which is what the
  generator writes); ``$PATH`` is replaced by the property shape's path.

Supported SHACL: targets (targetClass, targetNode, targetSubjectsOf,
targetObjectsOf), property paths, class, datatype, nodeKind, in, hasValue,
min/max Inclusive/Exclusive, min/maxLength, pattern, minCount, maxCount, node,
not, and, or, xone, sparql, severity, deactivated, message. Anything else
raises :class:`ShapesError` rather than being skipped silently.
"""

from __future__ import annotations

import itertools
import os
import re
from concurrent.futures import ThreadPoolExecutor
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pyoxigraph as ox

from stepnc_graph.outbound import OutboundRefused, refuse_outbound
from stepnc_graph.validate.shapes import RDF_TYPE, SH, ShapesError, ShapesGraph, literal_text, sh

XSD = "http://www.w3.org/2001/XMLSchema#"
P21_NS = "https://w3id.org/stepnc-graph/p21#"
FOCUS = "FOCUS_PATTERN"
TARGETS = ("targetClass", "targetNode", "targetSubjectsOf", "targetObjectsOf")
VALUE_PARAMS = ("class", "datatype", "nodeKind", "in", "hasValue", "minInclusive", "maxInclusive",
                "minExclusive", "maxExclusive", "minLength", "maxLength", "pattern", "node", "not", "and",
                "or", "xone")
KNOWN = set(VALUE_PARAMS) | {"minCount", "maxCount", "sparql", "property", "path", "severity", "message",
                             "deactivated", "name", "description", "order", "group", "flags", *TARGETS,
                             "prefixes", "declare", "select", "prefix", "namespace", "closed", "ignoredProperties"}
COMPONENT = {
    "class": "ClassConstraintComponent", "datatype": "DatatypeConstraintComponent",
    "nodeKind": "NodeKindConstraintComponent", "in": "InConstraintComponent",
    "hasValue": "HasValueConstraintComponent", "minInclusive": "MinInclusiveConstraintComponent",
    "maxInclusive": "MaxInclusiveConstraintComponent", "minExclusive": "MinExclusiveConstraintComponent",
    "maxExclusive": "MaxExclusiveConstraintComponent", "minLength": "MinLengthConstraintComponent",
    "maxLength": "MaxLengthConstraintComponent", "pattern": "PatternConstraintComponent",
    "node": "NodeConstraintComponent", "not": "NotConstraintComponent", "and": "AndConstraintComponent",
    "or": "OrConstraintComponent", "xone": "XoneConstraintComponent", "minCount": "MinCountConstraintComponent",
    "maxCount": "MaxCountConstraintComponent", "sparql": "SPARQLConstraintComponent",
}
FACET_OP = {"minInclusive": ">=", "maxInclusive": "<=", "minExclusive": ">", "maxExclusive": "<"}
NODE_KINDS = {
    "IRI": "isIRI({v})", "BlankNode": "isBlank({v})", "Literal": "isLiteral({v})",
    "BlankNodeOrIRI": "(isIRI({v}) || isBlank({v}))", "BlankNodeOrLiteral": "(isBlank({v}) || isLiteral({v}))",
    "IRIOrLiteral": "(isIRI({v}) || isLiteral({v}))",
}


@dataclass(frozen=True)
class Check:
    """One constraint of one shape, as a SELECT yielding ``?this`` (and maybe ``?value``) per result."""

    shape: str  # the source shape (N-Triples term)
    constraint: str  # the parameter (class, minCount, sparql, ...)
    component: str  # the constraint component IRI
    path: str | None  # SPARQL path text of a property shape
    path_term: str | None  # the sh:path term in the shapes graph
    severity: str
    query: str  # holds FOCUS where the focus pattern goes
    classes: frozenset[str] = field(default=frozenset())  # target classes, subclasses included
    closures: tuple[frozenset[str], ...] = ()  # one per sh:targetClass
    other_targets: tuple[str, ...] = ()  # patterns binding ?this for the other kinds of target
    parent: str | None = None  # the node shape holding a property shape
    sparql_node: str | None = None  # the sh:sparql node (for its message)
    #: positions of the shape files that describe a result of this check (its shapes, the
    #: constraint's argument): describing reads only those
    files: tuple[int, ...] = ()
    #: the constraint's argument (its sh:class, sh:maxCount ... object), None for sh:sparql
    argument: str | None = None
    #: when the Part 21 mapping guarantees the check (:mod:`.implied`), None when it does not
    implied: str | None = None
    #: an sh:not of classes (ONEOF) can fail only on a node with two rdf:types, or on a node of one
    #: of the target classes listed here (a class below both sides, e.g. vertex_point): the check
    #: runs only then. None: a check that always runs
    excludes: frozenset[str] | None = None


class Compiler:
    """Turns every targeted shape of a :class:`ShapesGraph` into :class:`Check` queries."""

    def __init__(self, graph: ShapesGraph) -> None:
        self.g = graph
        self.counter = itertools.count(1)

    def fresh(self, stem: str = "x") -> str:
        return f"?_{stem}{next(self.counter)}"

    # -- shapes ------------------------------------------------------------------------------

    def checks(self) -> list[Check]:
        out: list[Check] = []
        targeted = sorted({s for t in TARGETS for s in self.g.subjects(sh(t))})
        for shape in targeted:
            if self.deactivated(shape):
                continue
            out.extend(self.shape_checks(shape, shape, None))
        return out

    def deactivated(self, shape: str) -> bool:
        return self.g.value(shape, sh("deactivated")) == f'"true"^^<{XSD}boolean>'

    def severity(self, shape: str) -> str:
        return self.g.value(shape, sh("severity")) or sh("Violation")

    def targets(self, shape: str) -> tuple[tuple[frozenset[str], ...], tuple[str, ...]]:
        """The class closures of the shape's targetClass, and patterns binding ``?this`` for its other targets."""
        closures: list[frozenset[str]] = []
        parts: list[str] = []
        for cls in self.g.objects(shape, sh("targetClass")):
            closure = self.g.closure(cls)
            closures.append(frozenset(closure))
            individuals = sorted(self.g.typed_individuals(closure))
            if individuals:  # typed in the support graph (enumeration items)
                parts.append(f"{{ VALUES ?this {{ {' '.join(individuals)} }} }}")
        for node in self.g.objects(shape, sh("targetNode")):
            parts.append(f"{{ BIND({node} AS ?this) }}")
        for p in self.g.objects(shape, sh("targetSubjectsOf")):
            parts.append(f"{{ SELECT DISTINCT ?this WHERE {{ ?this {p} ?_o }} }}")
        for p in self.g.objects(shape, sh("targetObjectsOf")):
            parts.append(f"{{ SELECT DISTINCT ?this WHERE {{ ?_s {p} ?this }} }}")
        return tuple(closures), tuple(parts)

    def shape_checks(self, shape: str, target_shape: str, parent: str | None) -> Iterator[Check]:
        closures, others = self.targets(target_shape)
        focus = FOCUS
        classes = frozenset().union(*closures) if closures else frozenset()
        self.check_known(shape)
        severity = self.severity(shape)
        path_term = self.g.value(shape, sh("path"))
        path = self.path(path_term) if path_term is not None else None

        def make(constraint: str, query: str, sparql_node: str | None = None, component: str | None = None,
                 argument: str | None = None, excludes: frozenset[str] | None = None) -> Check:
            return Check(shape, constraint, component or f"<{SH}{COMPONENT[constraint]}>", path, path_term,
                         severity, query, classes, closures, others, parent, sparql_node,
                         self.describing_files(shape, parent, constraint, sparql_node), argument, None, excludes)

        value = "?value"
        values = f"?this {path} ?value ." if path is not None else "BIND(?this AS ?value)"
        for param in VALUE_PARAMS:
            for arg in self.g.objects(shape, sh(param)):
                if param == "node":
                    # one query per way the nested shape can fail: Oxigraph evaluates
                    # FILTER (NOT) EXISTS over property paths without the outer
                    # binding (quadratic), positive joins and OPTIONALs with it
                    patterns = self.witnesses(arg, value)
                    if patterns is not None:
                        for w in patterns:
                            yield make(param, f"SELECT DISTINCT ?this ?value WHERE {{ {focus} {values} {w} }}",
                                       argument=arg)
                        continue
                ok = self.value_ok(param, arg, value, shape, path)
                excluded = self.excluded_classes(arg) if param == "not" and path is None and not others else None
                if excluded is not None and classes:
                    yield make(param, f"SELECT ?this ?value WHERE {{ {focus} {values} FILTER(!({ok})) }}",
                               argument=arg, excludes=excluded & classes)
                    continue
                if param == "hasValue" and path is not None:
                    yield make(param, f"SELECT ?this WHERE {{ {focus} FILTER NOT EXISTS {{ ?this {path} {arg} }} }}",
                               argument=arg)
                    continue
                yield make(param, f"SELECT ?this ?value WHERE {{ {focus} {values} FILTER(!({ok})) }}", argument=arg)
        if path is not None:
            for arg in self.g.objects(shape, sh("minCount")):
                n = int(literal_text(arg))
                if n == 1:
                    q = f"SELECT ?this WHERE {{ {focus} FILTER NOT EXISTS {{ ?this {path} ?_v }} }}"
                else:
                    q = (f"SELECT ?this WHERE {{ {{ SELECT ?this (COUNT(DISTINCT ?_v) AS ?_n) WHERE {{ {focus} "
                         f"OPTIONAL {{ ?this {path} ?_v }} }} GROUP BY ?this }} FILTER(?_n < {n}) }}")
                if n > 0:
                    yield make("minCount", q, argument=arg)
            for arg in self.g.objects(shape, sh("maxCount")):
                n = int(literal_text(arg))
                q = (f"SELECT ?this WHERE {{ {focus} ?this {path} ?_v }} GROUP BY ?this "
                     f"HAVING (COUNT(DISTINCT ?_v) > {n})")
                yield make("maxCount", q, argument=arg)
        for node in self.g.objects(shape, sh("sparql")):
            if self.deactivated(node):
                continue
            yield make("sparql", self.sparql_query(node, focus, path), node)
        for prop in self.g.objects(shape, sh("property")):
            if not self.deactivated(prop):
                yield from self.shape_checks(prop, target_shape, shape)

    def describing_files(self, shape: str, parent: str | None, constraint: str, sparql_node: str | None) -> tuple[int, ...]:
        """The files a result of this check is described from: those of its shape, the node shape
        holding it, its sh:sparql node and the constraint's arguments."""
        nodes = [shape, parent, sparql_node, *self.g.objects(shape, sh(constraint))]
        return tuple(sorted({self.g.origin[n] for n in nodes if n is not None and n in self.g.origin}))

    def excluded_classes(self, shape: str) -> frozenset[str] | None:
        """When ``shape`` is ``sh:class`` or ``sh:or`` of ``sh:class`` only: every class it admits
        (subclasses included); None for any other shape.

        Then ``sh:not shape`` on a node with one rdf:type fails only if that
        type is one of them: a graph whose nodes have one type each, none of
        them admitted, needs no query (:func:`run`).
        """
        alternatives = [shape]
        ors = self.g.objects(shape, sh("or"))
        if ors:
            alternatives = self.g.items(ors[0])
            if set(self.g.predicates(shape)) - {RDF_TYPE} != {sh("or")}:
                return None
        admitted: set[str] = set()
        for alt in alternatives:
            if set(self.g.predicates(alt)) - {RDF_TYPE} != {sh("class")}:
                return None
            admitted |= self.g.closure(self.g.objects(alt, sh("class"))[0])
        return frozenset(admitted)

    def check_known(self, shape: str) -> None:
        for p in self.g.predicates(shape):
            if p.startswith(f"<{SH}"):
                name = p[len(SH) + 1:-1]
                if name not in KNOWN:
                    raise ShapesError(f"{shape} uses sh:{name}, which stepnc-graph's engine does not run")

    # -- paths --------------------------------------------------------------------------------

    def path(self, term: str) -> str:
        """A SHACL property path as SPARQL path syntax."""
        if term.startswith("<"):
            return term
        if self.g.value(term, "<http://www.w3.org/1999/02/22-rdf-syntax-ns#first>") is not None:
            return "(" + "/".join(self.path(t) for t in self.g.items(term)) + ")"
        for kind, fmt in (("inversePath", "^{}"), ("zeroOrMorePath", "{}*"), ("oneOrMorePath", "{}+"),
                          ("zeroOrOnePath", "{}?")):
            inner = self.g.value(term, sh(kind))
            if inner is not None:
                return "(" + fmt.format(self.path(inner)) + ")"
        alt = self.g.value(term, sh("alternativePath"))
        if alt is not None:
            return "(" + "|".join(self.path(t) for t in self.g.items(alt)) + ")"
        raise ShapesError(f"unsupported property path {term}")

    # -- value constraints as boolean SPARQL expressions ------------------------------------

    def value_ok(self, param: str, arg: str, v: str, shape: str, path: str | None) -> str:
        """SPARQL boolean: value ``v`` meets ``sh:param arg``."""
        if param == "class":
            closure = " ".join(sorted(self.g.closure(arg)))
            t = self.fresh("t")
            test = f"EXISTS {{ {v} {RDF_TYPE} {t} . VALUES {t} {{ {closure} }} }}"
            individuals = sorted(self.g.typed_individuals(self.g.closure(arg)))
            return f"({test} || {v} IN ({', '.join(individuals)}))" if individuals else test
        if param == "datatype":
            return f"(isLiteral({v}) && sameTerm(datatype({v}), {arg}))"
        if param == "nodeKind":
            kind = arg[len(SH) + 1:-1]
            return NODE_KINDS[kind].format(v=v)
        if param == "in":
            items = self.g.items(arg)
            if all(i.startswith("<") for i in items):
                return f"({v} IN ({', '.join(items)}))"
            return "(" + " || ".join(f"sameTerm({v}, {i})" for i in items) + ")" if items else "false"
        if param == "hasValue":
            return f"sameTerm({v}, {arg})"
        if param in FACET_OP:
            return f"COALESCE({v} {FACET_OP[param]} {arg}, false)"
        if param in ("minLength", "maxLength"):
            op = ">=" if param == "minLength" else "<="
            return f"(!isBlank({v}) && COALESCE(STRLEN(STR({v})) {op} {literal_text(arg)}, false))"
        if param == "pattern":
            flags = self.g.value(shape, sh("flags"))
            extra = f", {flags}" if flags else ""
            return f"(!isBlank({v}) && COALESCE(REGEX(STR({v}), {arg}{extra}), false))"
        if param == "node":
            return self.conforms(arg, v)
        if param == "not":
            return f"!{self.conforms(arg, v)}"
        members = [self.conforms(s, v) for s in self.g.items(arg)]
        if param == "and":
            return "(" + " && ".join(members) + ")" if members else "true"
        if param == "or":
            return "(" + " || ".join(members) + ")" if members else "false"
        if param == "xone":
            counts = " + ".join(f"IF({m}, 1, 0)" for m in members)
            return f"(({counts}) = 1)" if members else "false"
        raise ShapesError(f"unsupported constraint sh:{param}")

    def witnesses(self, shape: str, v: str) -> list[str] | None:
        """Graph patterns, one per way node ``v`` can fail ``shape``: ``v`` fails iff one matches.

        None when the shape needs a logical combination (not/and/or/xone) or
        counts above one, which stay boolean expressions (:meth:`conforms`).
        """
        self.check_known(shape)
        if self.deactivated(shape):
            return []
        out: list[str] = []
        path_term = self.g.value(shape, sh("path"))
        for param in VALUE_PARAMS:
            for arg in self.g.objects(shape, sh(param)):
                if path_term is not None:
                    continue
                if param in ("not", "and", "or", "xone"):
                    return None
                if param == "node":
                    inner = self.witnesses(arg, v)
                    if inner is None:
                        return None
                    out += inner
                else:
                    out.append(f"FILTER(!({self.value_ok(param, arg, v, shape, None)}))")
        if path_term is not None:
            path = self.path(path_term)
            for arg in self.g.objects(shape, sh("minCount")):
                n = int(literal_text(arg))
                if n > 1:
                    return None
                if n == 1:
                    x = self.fresh("m")
                    out.append(f"OPTIONAL {{ {v} {path} {x} }} FILTER(!bound({x}))")
            for arg in self.g.objects(shape, sh("maxCount")):
                xs = [self.fresh("c") for _ in range(int(literal_text(arg)) + 1)]
                distinct = " && ".join(f"!sameTerm({a}, {b})" for a, b in itertools.combinations(xs, 2))
                out.append(" ".join(f"{v} {path} {x} ." for x in xs) + (f" FILTER({distinct})" if distinct else ""))
            for param in VALUE_PARAMS:
                for arg in self.g.objects(shape, sh(param)):
                    x = self.fresh("pv")
                    if param in ("not", "and", "or", "xone"):
                        return None
                    if param == "hasValue":
                        m = self.fresh("m")
                        out.append(f"OPTIONAL {{ {v} {path} {m} FILTER(sameTerm({m}, {arg})) }} FILTER(!bound({m}))")
                    elif param == "node":
                        inner = self.witnesses(arg, x)
                        if inner is None:
                            return None
                        out += [f"{v} {path} {x} . {w}" for w in inner]
                    else:
                        out.append(f"{v} {path} {x} . FILTER(!({self.value_ok(param, arg, x, shape, path)}))")
        for node in self.g.objects(shape, sh("sparql")):
            out.append(self.sparql_body(node, v, self.path(path_term) if path_term else None))
        for prop in self.g.objects(shape, sh("property")):
            inner = self.witnesses(prop, v)
            if inner is None:
                return None
            out += inner
        return out

    def conforms(self, shape: str, v: str) -> str:
        """SPARQL boolean: node ``v`` conforms to ``shape`` (every constraint, property shapes included)."""
        self.check_known(shape)
        if self.deactivated(shape):
            return "true"
        tests: list[str] = []
        path_term = self.g.value(shape, sh("path"))
        if path_term is None:
            for param in VALUE_PARAMS:
                tests += [self.value_ok(param, arg, v, shape, None) for arg in self.g.objects(shape, sh(param))]
        else:
            tests += self.property_ok(shape, self.path(path_term), v)
        for node in self.g.objects(shape, sh("sparql")):
            body = self.sparql_body(node, v, self.path(path_term) if path_term else None)
            tests.append(f"NOT EXISTS {{ {body} }}")
        for prop in self.g.objects(shape, sh("property")):
            if not self.deactivated(prop):
                tests.append(self.conforms(prop, v))
        return "(" + " && ".join(tests) + ")" if tests else "true"

    def property_ok(self, shape: str, path: str, v: str) -> list[str]:
        tests: list[str] = []
        for arg in self.g.objects(shape, sh("minCount")):
            tests.append(self.at_least(v, path, int(literal_text(arg))))
        for arg in self.g.objects(shape, sh("maxCount")):
            tests.append(f"!{self.at_least(v, path, int(literal_text(arg)) + 1)}")
        for param in VALUE_PARAMS:
            for arg in self.g.objects(shape, sh(param)):
                if param == "hasValue":
                    tests.append(f"EXISTS {{ {v} {path} {arg} }}")
                    continue
                x = self.fresh("pv")
                tests.append(f"NOT EXISTS {{ {v} {path} {x} . FILTER(!({self.value_ok(param, arg, x, shape, path)})) }}")
        return tests

    def at_least(self, v: str, path: str, n: int) -> str:
        if n <= 0:
            return "true"
        xs = [self.fresh("c") for _ in range(n)]
        pattern = " ".join(f"{v} {path} {x} ." for x in xs)
        distinct = " && ".join(f"!sameTerm({a}, {b})" for a, b in itertools.combinations(xs, 2))
        return f"EXISTS {{ {pattern}{f' FILTER({distinct})' if distinct else ''} }}"

    # -- SHACL-SPARQL -----------------------------------------------------------------------

    def prefixes(self, node: str) -> str:
        lines = []
        for owner in self.g.objects(node, sh("prefixes")):
            for decl in self.g.objects(owner, sh("declare")):
                prefix = literal_text(self.g.value(decl, sh("prefix")) or "")
                ns = literal_text(self.g.value(decl, sh("namespace")) or "")
                lines.append(f"PREFIX {prefix}: <{ns}>")
        return " ".join(lines)

    def select_text(self, node: str) -> str:
        select = self.g.value(node, sh("select"))
        if select is None:
            raise ShapesError(f"{node}: a SPARQL constraint without sh:select")
        text = literal_text(select).replace("\\n", "\n").replace("\\t", "\t")
        if re.search(r"\$(currentShape|shapesGraph)\b", text):
            raise ShapesError(f"{node}: $currentShape and $shapesGraph are not supported")
        return text

    def sparql_query(self, node: str, focus: str, path: str | None) -> str:
        """The constraint's SELECT with the focus pattern put first in its WHERE clause."""
        text = self.select_text(node)
        if path is not None:
            text = text.replace("$PATH", path)
        text = re.sub(r"\$this\b", "?this", text)
        where = re.search(r"\bWHERE\s*\{", text, re.IGNORECASE) or re.search(r"\{", text)
        if where is None:
            raise ShapesError(f"{node}: no WHERE clause")
        text = f"{text[:where.end()]} {focus} {text[where.end():]}"
        return f"{self.prefixes(node)} {text}"

    def sparql_body(self, node: str, v: str, path: str | None) -> str:
        """The WHERE group of a SPARQL constraint used inside a nested shape, ``$this`` := ``v``."""
        text = self.select_text(node)
        if path is not None:
            text = text.replace("$PATH", path)
        if self.prefixes(node):
            text = self.expand_prefixes(node, text)
        start = text.index("{", re.search(r"\bWHERE\b", text, re.IGNORECASE).end())  # type: ignore[union-attr]
        end = text.rindex("}")
        return re.sub(r"\$this\b", v, text[start + 1:end])

    def expand_prefixes(self, node: str, text: str) -> str:
        for owner in self.g.objects(node, sh("prefixes")):
            for decl in self.g.objects(owner, sh("declare")):
                prefix = literal_text(self.g.value(decl, sh("prefix")) or "")
                ns = literal_text(self.g.value(decl, sh("namespace")) or "")
                text = re.sub(rf"(?<![\w<]){prefix}:([A-Za-z_][\w.-]*\w|[A-Za-z_])", rf"<{ns}\1>", text)
        return text


@dataclass(frozen=True)
class Row:
    """One raw result of a check: the focus node and value (pyoxigraph terms)."""

    check: Check
    focus: ox.NamedNode | ox.BlankNode | ox.Literal
    value: ox.NamedNode | ox.BlankNode | ox.Literal | None


def focus_pattern(check: Check, present: set[str]) -> str | None:
    """The pattern binding ``?this`` to the check's focus nodes in a graph with classes ``present``.

    Only the target classes that occur are listed (a smaller join); None when
    the check has no focus node there.
    """
    parts = [f"{{ ?this a ?_t . VALUES ?_t {{ {' '.join(sorted(c & present))} }} }}"
             for c in check.closures if c & present]
    parts += check.other_targets
    return " UNION ".join(parts) if parts else None


#: Checks run on this many threads: Oxigraph evaluates a query without the GIL, so two cores
#: run two checks at once (measured, 118 checks on 100k instances in memory: 0.59 s on one
#: thread, 0.35 s on two; results identical).
CHECK_THREADS = max(1, min(4, os.cpu_count() or 1))


def refuse_service(checks: list[Check], allow: bool = False) -> None:
    """Raise ShapesError if a check's SPARQL (an sh:sparql constraint's, or one built from a shape)
    would send a request to another server (``SERVICE``), unless ``allow``: every check, whether
    or not the graph has focus nodes for it, so that a shapes file is refused whatever the data."""
    if allow:
        return
    for check in checks:
        try:
            refuse_outbound(check.query.replace(FOCUS, "{}"))
        except OutboundRefused as exc:
            raise ShapesError(f"shape {check.shape}, its {check.constraint} constraint: {exc}") from None


def run(store: ox.Store, graph: str, checks: list[Check], skip: frozenset[str] = frozenset(),
        allow_service: bool = False) -> tuple[list[Row], int]:
    """Run the checks whose targets occur in ``graph``; the rows, and how many checks ran.

    Checks whose :attr:`Check.implied` is in ``skip`` are not run (see :mod:`.implied`).
    They run on :data:`CHECK_THREADS` threads; the rows come in the order of ``checks``
    whatever the threads' timing. A check with a ``SERVICE`` clause is refused (ShapesError)
    unless ``allow_service``."""
    refuse_service(checks, allow_service)
    g = ox.NamedNode(graph)
    present = {str(s[0]) for s in store.query("SELECT DISTINCT ?t WHERE { ?s a ?t }", default_graph=g)}  # type: ignore[union-attr]
    # a node with two types that a class target can reach: not the file node (p21:ExchangeStructure, prov:Entity)
    multi_typed = bool(store.query(f"ASK {{ ?s a ?t1 , ?t2 FILTER(!sameTerm(?t1, ?t2)) "
                                   f"FILTER NOT EXISTS {{ ?s a <{P21_NS}ExchangeStructure> }} }}", default_graph=g))
    todo: list[tuple[Check, str]] = []
    for check in checks:
        focus = focus_pattern(check, present)
        if focus is None or check.implied in skip or (
                check.excludes is not None and not multi_typed and not check.excludes & present):
            continue
        todo.append((check, check.query.replace(FOCUS, focus)))

    def evaluate(item: tuple[Check, str]) -> list[tuple[Any, Any]]:
        results = store.query(item[1], default_graph=g)
        has_value = any(v.value == "value" for v in results.variables)  # type: ignore[union-attr]
        return [(s["this"], s["value"] if has_value else None)
                for s in results if s["this"] is not None]  # type: ignore[union-attr]

    with ThreadPoolExecutor(CHECK_THREADS) as pool:
        found = list(pool.map(evaluate, todo))
    rows: list[Row] = []
    seen: set[tuple[str, str, str, str]] = set()
    for (check, _), solutions in zip(todo, found, strict=True):
        for focus_node, value in solutions:
            key = (check.shape, check.constraint, str(focus_node), str(value))
            if key not in seen:  # a nested shape's ways to fail can match the same value twice
                seen.add(key)
                rows.append(Row(check, focus_node, value))
    return rows, len(todo)
