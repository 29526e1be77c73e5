"""SHACL compiled to SPARQL and run by the embedded Oxigraph store.

Why not a SHACL library: pySHACL needs an rdflib copy of the data (about 28 s
of parsing alone for 100k instances) and its SPARQL-based constraints run one
query per focus node; measured in ``bench/validate_bench.py``. Here every use
of a constraint component in a targeted shape becomes **one** SELECT over the
whole data graph, Oxigraph evaluates it in Rust on the data already in the
store, and only the checks whose target classes occur in the graph run
(:mod:`.runner` runs them; this module compiles them).

The compiler keeps what is common to all components -- targets (explicit and
implicit class targets, SHACL 2.1.3), property paths (2.3.1), the nesting of
shapes and the dispatch -- and each component (:mod:`.components`) writes its
own queries. How the SHACL semantics is kept:

* **Class membership** uses the data graph's hierarchy: ``shapes/support.ttl``
  (defined to be part of every data graph the shipped shapes run on) is compiled
  in, and the data graph's own ``rdfs:subClassOf`` triples are read when the
  checks run. Queries hold placeholders (``⟦CLASS ?v <C>⟧``, ``⟦FOCUS ?v⟧``,
  ``⟦DATATYPE ?v <D>⟧``) expanded then, so compiled checks serve any data.
  The shapes graph's own type and subclass triples are not data.
* **Nesting.** ``sh:property`` of a property shape validates the value nodes
  (its checks' focus pattern is the parent's value pattern); ``sh:node``,
  ``sh:not``, ``sh:and``, ``sh:or``, ``sh:xone`` and ``sh:qualifiedValueShape``
  compile the nested shape to a boolean SPARQL expression, or for ``sh:node``
  to one query per way it can fail (Oxigraph joins those with the binding).
* **Recursion** (a shape reaching itself through those parameters), which SHACL
  leaves undefined, is refused with the cycle named (:class:`UnsupportedShapes`).
* **SHACL-SPARQL** (:mod:`.sparql`): ``$this`` pre-bound by the focus pattern in
  every group that needs it; the forms SHACL forbids refused.

Anything the engine does not run raises :class:`ShapesError` rather than being
skipped silently.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field


from stepnc_graph.validation import components as C
from stepnc_graph.validation.shapes import (
    RDF_FIRST,
    RDFS,
    SH,
    IllFormedShapes,
    ShapesGraph,
    UnsupportedShapes,
    literal_text,
    sh,
)

XSD = "http://www.w3.org/2001/XMLSchema#"
P21_NS = "https://w3id.org/stepnc-graph/p21#"
TARGETS = ("targetClass", "targetNode", "targetSubjectsOf", "targetObjectsOf")
#: the named graph a query reads as ``$shapesGraph`` (loaded only when a check names it)
SHAPES_GRAPH = "urn:stepnc-graph:validate:shapes-graph"
RDFS_CLASS = f"<{RDFS}Class>"
OWL_IMPORTS = "<http://www.w3.org/2002/07/owl#imports>"
SUBCLASS_OF = f"<{RDFS}subClassOf>"

FOCUS_MARK = re.compile(r"⟦FOCUS (\?\w+)⟧")
CLASS_MARK = re.compile(r"⟦CLASS (\?\w+) (<[^>]*>)⟧")
DATATYPE_MARK = re.compile(r"⟦DATATYPE (\?\w+) (<[^>]*>)⟧")


@dataclass(frozen=True)
class Check:
    """One use of a component in a shape, as a SELECT yielding ``?this`` (and maybe ``?value``,
    ``?path``) per result."""

    shape: str  # the source shape (N-Triples term)
    constraint: str  # the component's key parameter (class, minCount, sparql, ...) or a custom component IRI
    component: str  # the constraint component IRI
    path: str | None  # SPARQL path text of a property shape
    path_term: str | None  # the sh:path term in the shapes graph
    severity: str
    query: str  # holds the ⟦...⟧ placeholders expanded by :func:`run`
    classes: frozenset[str] = field(default=frozenset())  # target classes, subclasses included
    closures: tuple[frozenset[str], ...] = ()  # one per class target (support hierarchy)
    other_targets: tuple[str, ...] = ()  # patterns binding ?this for the other kinds of target
    parent: str | None = None  # the shape holding a property shape
    sparql_node: str | None = None  # the sh:sparql node or validator (its messages)
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
    #: the target classes themselves (closures are recomputed when the data graph has subclasses)
    target_classes: tuple[str, ...] = ()
    #: the component's parameter values (name, term), for messages
    args: tuple[tuple[str, str], ...] = ()
    #: a property shape nested in a property shape: a pattern binding ``?this`` once per way a
    #: root focus node reaches it (a value node reached twice is validated, and reported, twice)
    multiplicity: str | None = None


class Compiler:
    """Turns every targeted shape of a :class:`ShapesGraph` into :class:`Check` queries."""

    def __init__(self, graph: ShapesGraph) -> None:
        self.g = graph
        self.counter = itertools.count(1)
        self.components: tuple[C.Component, ...] = (*C.REGISTRY, *C.custom_components(graph))
        self._stack: list[str] = []
        self._uses: dict[str, list[tuple[C.Component, C.Use]]] = {}

    def fresh(self, stem: str = "x") -> str:
        return f"?_{stem}{next(self.counter)}"

    # -- shapes ------------------------------------------------------------------------------

    def checks(self) -> list[Check]:
        out: list[Check] = []
        for shape in self.targeted():
            if self.deactivated(shape):
                continue
            root = self.root_focus
            out.extend(self.shape_checks(shape, shape, root, None, (), None))
        return out

    @staticmethod
    def root_focus(var: str) -> str:
        return f"⟦FOCUS {var}⟧"

    def targeted(self) -> list[str]:
        """Shapes with a target, explicit or implicit (a shape that is an rdfs:Class, SHACL 2.1.3.3)."""
        found = {s for t in TARGETS for s in self.g.subjects(sh(t))}
        found |= {s for s in self.g.instances_of(RDFS_CLASS) if self.implicit_class(s)}
        return sorted(found)

    def implicit_class(self, shape: str) -> bool:
        return self.g.is_instance(shape, RDFS_CLASS) and (
            self.g.is_instance(shape, sh("NodeShape")) or self.g.is_instance(shape, sh("PropertyShape")))

    def deactivated(self, shape: str) -> bool:
        return self.g.value(shape, sh("deactivated")) == C.TRUE

    def severity(self, shape: str) -> str:
        value = self.g.value(shape, sh("severity"))
        if value is not None and not value.startswith("<"):
            raise IllFormedShapes(f"{shape}: sh:severity {value} is not an IRI")
        return value or sh("Violation")

    def targets(self, shape: str) -> tuple[tuple[str, ...], tuple[frozenset[str], ...], tuple[str, ...]]:
        """The shape's target classes, their closures (support hierarchy) and patterns binding
        ``?this`` for its other targets."""
        classes = [c for c in self.g.objects(shape, sh("targetClass"))]
        if self.implicit_class(shape):
            classes.append(shape)
        parts: list[str] = []
        closures: list[frozenset[str]] = []
        for cls in classes:
            if not cls.startswith("<"):
                raise UnsupportedShapes(f"{shape}: a blank node as target class")
            closure = self.g.closure(cls)
            closures.append(frozenset(closure))
            individuals = sorted(self.g.typed_individuals(closure))
            if individuals:  # typed in the support graph (enumeration items)
                parts.append(f"{{ VALUES ?this {{ {' '.join(individuals)} }} }}")
        for node in self.g.objects(shape, sh("targetNode")):
            if node.startswith("_:"):
                raise UnsupportedShapes(f"{shape}: a blank node as sh:targetNode")
            parts.append(f"{{ BIND({node} AS ?this) }}")
        for p in self.g.objects(shape, sh("targetSubjectsOf")):
            parts.append(f"{{ SELECT DISTINCT ?this WHERE {{ ?this {self.iri(p, shape)} ?_o }} }}")
        for p in self.g.objects(shape, sh("targetObjectsOf")):
            parts.append(f"{{ SELECT DISTINCT ?this WHERE {{ ?_s {self.iri(p, shape)} ?this }} }}")
        return tuple(classes), tuple(closures), tuple(parts)

    @staticmethod
    def iri(term: str, shape: str) -> str:
        if not term.startswith("<"):
            raise IllFormedShapes(f"{shape}: {term} must be an IRI")
        return term

    def uses(self, shape: str) -> list[tuple[C.Component, C.Use]]:
        """Every use of a component in ``shape`` (its constraints), checked for what the engine runs."""
        if shape in self._uses:
            return self._uses[shape]
        self.check_known(shape)
        paths = self.g.objects(shape, sh("path"))
        if len(paths) > 1:
            raise IllFormedShapes(f"{shape} has {len(paths)} values of sh:path")
        path_term = paths[0] if paths else None
        path = self.path(path_term) if path_term is not None else None
        out = [(comp, use) for comp in self.components for use in comp.uses(self.g, shape, path, path_term)]
        self._uses[shape] = out
        return out

    def shape_checks(self, shape: str, target_shape: str, focus: Callable[[str], str], parent: str | None,
                     trail: tuple[str, ...], chain: Callable[[str], str] | None) -> Iterator[Check]:
        """The checks of ``shape``, its focus nodes bound by ``focus(var)``; nested property shapes
        get the value nodes of their parent as focus nodes (SHACL 4.7.2); ``chain(var)`` binds them
        once per way they are reached (None: each focus node once)."""
        if shape in trail:
            raise UnsupportedShapes(f"recursive shapes (sh:property): {' -> '.join((*trail, shape))}")
        target_classes, closures, others = self.targets(target_shape)
        classes = frozenset().union(*closures) if closures else frozenset()
        severity = self.severity(shape)
        for comp, use in self.uses(shape):
            if isinstance(comp, C.PropertyComponent):
                prop = use.args["property"]
                if self.deactivated(prop):
                    continue
                if use.path is None:
                    nested, nested_chain = focus, chain
                else:
                    nested = self.value_focus(focus, use.path, True)
                    nested_chain = self.value_focus(chain or focus, use.path, False)
                yield from self.shape_checks(prop, target_shape, nested, shape, (*trail, shape), nested_chain)
                continue
            self._stack = []
            for v in comp.violations(self, use, focus("?this")):
                yield Check(shape, comp.key or comp.iri, f"<{comp.iri}>", use.path, use.path_term, severity,
                            v.query, classes, closures, others, parent, v.node,
                            self.describing_files(shape, parent, use, v.node), use.args.get(comp.key), None,
                            v.excludes & classes if v.excludes is not None and classes and not others else None,
                            target_classes, tuple(use.args.items()),
                            chain("?this") if chain is not None else None)

    def value_focus(self, focus: Callable[[str], str], path: str, distinct: bool) -> Callable[[str], str]:
        """The focus pattern of a property shape nested in a property shape: the parent's value
        nodes (``distinct``: each once)."""
        outer = self.fresh("f")
        select = "SELECT DISTINCT" if distinct else "SELECT"
        return lambda var: f"{{ {select} {var} WHERE {{ {focus(outer)} {outer} {path} {var} }} }}"

    def describing_files(self, shape: str, parent: str | None, use: C.Use, node: str | None) -> tuple[int, ...]:
        """The files a result of this check is described from: those of its shape, the shape
        holding it, its SPARQL node and the constraint's arguments."""
        nodes = [shape, parent, node, *use.args.values()]
        return tuple(sorted({self.g.origin[n] for n in nodes if n is not None and n in self.g.origin}))

    def check_known(self, shape: str) -> None:
        for p in self.g.predicates(shape):
            if p.startswith(f"<{SH}"):
                name = p[len(SH) + 1:-1]
                if name not in C.PARAMETERS and name not in C.NON_VALIDATING:
                    raise UnsupportedShapes(f"{shape} uses sh:{name}, which stepnc-graph's engine does not run")

    # -- nested shapes ----------------------------------------------------------------------

    def _enter(self, shape: str) -> None:
        if shape in self._stack:
            cycle = self._stack[self._stack.index(shape):] + [shape]
            raise UnsupportedShapes("recursive shapes, which SHACL leaves undefined: " + " -> ".join(cycle))
        self._stack.append(shape)

    def conforms(self, shape: str, v: str) -> str:
        """SPARQL boolean: node ``v`` conforms to ``shape`` (every constraint, property shapes included)."""
        if self.deactivated(shape):
            return "true"
        self._enter(shape)
        try:
            tests = [comp.holds(self, use, v) for comp, use in self.uses(shape)]
        finally:
            self._stack.pop()
        tests = [t for t in tests if t != "true"]
        return "(" + " && ".join(tests) + ")" if tests else "true"

    def witnesses(self, shape: str, v: str) -> list[str] | None:
        """Graph patterns, one per way node ``v`` can fail ``shape``: ``v`` fails iff one matches.
        None when a constraint has only the boolean form (:meth:`conforms`)."""
        if self.deactivated(shape):
            return []
        self._enter(shape)
        try:
            out: list[str] = []
            for comp, use in self.uses(shape):
                found = comp.witnesses(self, use, v)
                if found is None:
                    return None
                out += found
            return out
        finally:
            self._stack.pop()

    # -- terms the components need ----------------------------------------------------------------

    def class_test(self, v: str, cls: str) -> str:
        if not cls.startswith("<"):
            raise UnsupportedShapes(f"a blank node ({cls}) as the value of sh:class")
        return f"⟦CLASS {v} {cls}⟧"

    def datatype_test(self, v: str, datatype: str) -> str:
        if not datatype.startswith("<"):
            raise IllFormedShapes(f"sh:datatype {datatype} is not an IRI")
        return f"⟦DATATYPE {v} {datatype}⟧"

    def prefixes(self, node: str) -> dict[str, str]:
        """The prefixes a SPARQL query may use (SHACL 5.2.1): the sh:declare values of its
        sh:prefixes nodes and of what those import (owl:imports), in the shapes graph."""
        out: dict[str, str] = {}
        owners = list(self.g.objects(node, sh("prefixes")))
        seen: set[str] = set()
        while owners:
            owner = owners.pop(0)
            if owner in seen:
                continue
            seen.add(owner)
            owners += self.g.objects(owner, OWL_IMPORTS)
            for decl in self.g.objects(owner, sh("declare")):
                prefix = self.g.value(decl, sh("prefix"))
                ns = self.g.value(decl, sh("namespace"))
                if prefix is None or ns is None:
                    raise IllFormedShapes(f"{owner}: an sh:declare without sh:prefix and sh:namespace")
                out[literal_text(prefix)] = literal_text(ns)
        return out

    def shapes_graph_iri(self) -> str:
        return f"<{SHAPES_GRAPH}>"

    def path(self, term: str, seen: frozenset[str] = frozenset()) -> str:
        """A SHACL property path (2.3.1) as SPARQL path syntax."""
        if term.startswith("<"):
            return term
        if term.startswith('"') or term in seen:
            raise IllFormedShapes(f"{term} is not a SHACL property path")
        seen = seen | {term}
        if self.g.value(term, RDF_FIRST) is not None:
            items = self.g.items(term)
            if len(items) < 2:
                raise IllFormedShapes(f"a sequence path needs two members at least: {term}")
            return "(" + "/".join(self.path(t, seen) for t in items) + ")"
        for kind, fmt in (("inversePath", "^{}"), ("zeroOrMorePath", "{}*"), ("oneOrMorePath", "{}+"),
                          ("zeroOrOnePath", "{}?")):
            inner = self.g.value(term, sh(kind))
            if inner is not None:
                return "(" + fmt.format(self.path(inner, seen)) + ")"
        alt = self.g.value(term, sh("alternativePath"))
        if alt is not None:
            items = self.g.items(alt)
            if len(items) < 2:
                raise IllFormedShapes(f"an alternative path needs two members at least: {term}")
            return "(" + "|".join(self.path(t, seen) for t in items) + ")"
        raise IllFormedShapes(f"{term} is not a SHACL property path")
