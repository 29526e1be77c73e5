"""A shapes graph as the engine reads it: triples indexed by subject, and the class hierarchy.

Read with pyoxigraph's Turtle parser (Rust; no rdflib at run time, which keeps
``validate`` of a small program fast). Terms are kept in N-Triples syntax
(``<iri>``, ``"lex"^^<dt>``, ``_:b1``), which is also their SPARQL syntax.
"""

from __future__ import annotations

import re
from collections import defaultdict
from collections.abc import Iterable, Mapping
from pathlib import Path

import pyoxigraph as ox

from stepnc_graph.core.errors import StepncGraphError

SH = "http://www.w3.org/ns/shacl#"
RDF = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
RDFS = "http://www.w3.org/2000/01/rdf-schema#"


def sh(name: str) -> str:
    return f"<{SH}{name}>"


RDF_TYPE, RDF_FIRST, RDF_REST, RDF_NIL = (f"<{RDF}{n}>" for n in ("type", "first", "rest", "nil"))
SUBCLASS = f"<{RDFS}subClassOf>"


class ShapesError(StepncGraphError):
    """A shapes file that cannot be read or uses SHACL the engine does not run."""


class IllFormedShapes(ShapesError):
    """A shapes graph SHACL says an engine must refuse (an ill-formed shape, a forbidden SPARQL form)."""


class UnsupportedShapes(ShapesError):
    """Well-formed SHACL this engine refuses to run rather than answer wrongly (each case documented)."""


def subclass_closure(subclasses: Mapping[str, Iterable[str]], cls: str) -> set[str]:
    """``cls`` and every class below it, ``subclasses`` giving each class's direct subclasses."""
    out = {cls}
    stack = [cls]
    while stack:
        for sub in subclasses.get(stack.pop(), ()):
            if sub not in out:
                out.add(sub)
                stack.append(sub)
    return out


class ShapesGraph:
    """Triples of the shapes (and support) files; ``objects(s, p)`` in file order."""

    def __init__(self) -> None:
        self._sp: dict[tuple[str, str], list[str]] = defaultdict(list)
        self._po: dict[tuple[str, str], list[str]] = defaultdict(list)
        self._preds: dict[str, list[str]] = defaultdict(list)
        self.subclasses: dict[str, set[str]] = defaultdict(set)  # class -> direct subclasses
        self.instances: dict[str, set[str]] = defaultdict(set)  # class -> individuals typed in these files
        #: subject -> position (0-based) of the file that first describes it
        self.origin: dict[str, int] = {}
        self._files = 0
        #: positions of the files whose triples belong to the data graph (shapes/support.ttl: the class
        #: hierarchy and the enumeration items' types, defined to be part of every data graph)
        self.data_files: set[int] = set()
        #: class -> direct subclasses, and class -> typed nodes, in the shapes graph proper (not data
        #: files): for implicit class targets and the types of shapes, validators and components
        self.shape_subclasses: dict[str, set[str]] = defaultdict(set)
        self.shape_instances: dict[str, set[str]] = defaultdict(set)

    def add_file(self, path: Path, position: int | None = None, data: bool = False) -> None:
        """Add a Turtle file (blank node labels kept apart per file)."""
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, ValueError) as exc:
            raise ShapesError(f"{path}: {exc}") from None
        self.add_text(text, str(path), position, data)

    def add_text(self, text: str, name: str, position: int | None = None, data: bool = False) -> None:
        """Add a Turtle document; ``name`` (its file) is for error messages and is the base of its
        relative IRIs (as any Turtle reader takes a file's IRI). ``position`` is the file's place in
        the full list of shape files (default: the next one): it names the file's blank nodes, so a
        graph of some of the files names them as the graph of all of them does. ``data``: the file's
        triples belong to the data graph (:attr:`data_files`)."""
        if position is None:
            position = self._files
        self._files = max(self._files, position + 1)
        if data:
            self.data_files.add(position)
        try:
            triples = list(ox.parse(text.encode("utf-8"), format=ox.RdfFormat.TURTLE, base_iri=base_iri(name)))
        except (SyntaxError, ValueError) as exc:
            raise ShapesError(f"{name}: {exc}") from None
        self.add(triples, f"f{position + 1}", position)

    def add(self, triples: Iterable[ox.Triple | ox.Quad], tag: str, position: int = 0) -> None:
        """Index triples. Blank nodes are renamed ``_:{tag}_b{n}`` in order of first appearance: the
        parser's own labels are random, and compiled checks (:mod:`.compiled`) name blank shapes that
        a graph parsed in another process must name the same way."""
        blanks: dict[str, str] = {}
        for t in triples:
            s, p, o = (self.term(t.subject, tag, blanks), self.term(t.predicate, tag, blanks),
                       self.term(t.object, tag, blanks))
            if (s, p) not in self._sp:
                self._preds[s].append(p)
                self.origin.setdefault(s, position)
            self._sp[(s, p)].append(o)
            self._po[(p, o)].append(s)
            data = position in self.data_files
            if p == SUBCLASS:
                (self.subclasses if data else self.shape_subclasses)[o].add(s)
            elif p == RDF_TYPE:
                (self.instances if data else self.shape_instances)[o].add(s)

    @staticmethod
    def term(node: object, tag: str, blanks: dict[str, str]) -> str:
        if isinstance(node, ox.BlankNode):
            label = blanks.get(node.value)
            if label is None:
                label = blanks[node.value] = f"_:{tag}_b{len(blanks)}"
            return label
        return str(node)

    # -- reading --------------------------------------------------------------------------------

    def objects(self, s: str, p: str) -> list[str]:
        return self._sp.get((s, p), [])

    def predicates(self, s: str) -> list[str]:
        return self._preds.get(s, [])

    def value(self, s: str, p: str) -> str | None:
        values = self._sp.get((s, p))
        return values[0] if values else None

    def subjects(self, p: str, o: str | None = None) -> list[str]:
        if o is not None:
            return self._po.get((p, o), [])
        return sorted({s for (s, pred) in self._sp if pred == p})

    def items(self, head: str) -> list[str]:
        """The members of an RDF list."""
        out: list[str] = []
        seen: set[str] = set()
        while head != RDF_NIL and head not in seen:
            seen.add(head)
            first = self.value(head, RDF_FIRST)
            if first is None:
                raise ShapesError(f"malformed RDF list at {head}")
            out.append(first)
            head = self.value(head, RDF_REST) or RDF_NIL
        return out

    def closure(self, cls: str) -> set[str]:
        """``cls`` and every class below it through rdfs:subClassOf."""
        return subclass_closure(self.subclasses, cls)

    def typed_individuals(self, classes: Iterable[str]) -> set[str]:
        """Individuals the data files type with one of ``classes`` (enumeration items); IRIs only."""
        return {i for c in classes for i in self.instances.get(c, ()) if i.startswith("<")}

    def is_instance(self, node: str, cls: str) -> bool:
        """Whether the shapes graph makes ``node`` a SHACL instance of ``cls`` (rdf:type, then
        rdfs:subClassOf in the shapes graph)."""
        return any(node in self.shape_instances.get(c, ()) for c in self.shape_closure(cls))

    def shape_closure(self, cls: str) -> set[str]:
        """``cls`` and its subclasses by the shapes graph's own rdfs:subClassOf triples."""
        out = {cls}
        stack = [cls]
        while stack:
            for sub in self.shape_subclasses.get(stack.pop(), ()):
                if sub not in out:
                    out.add(sub)
                    stack.append(sub)
        return out

    def instances_of(self, cls: str) -> set[str]:
        """The SHACL instances of ``cls`` in the shapes graph."""
        return {n for c in self.shape_closure(cls) for n in self.shape_instances.get(c, ())}


def base_iri(name: str) -> str:
    """The IRI of a shapes file named ``name`` (a path): the base of its relative IRIs."""
    if "://" in name or name.startswith("urn:"):
        return name
    return Path(name).resolve().as_uri()


def literal_text(term: str) -> str:
    """The lexical form of a literal in N-Triples syntax."""
    if not term.startswith('"'):
        return term
    end = term.rindex('"')
    return _ESCAPE.sub(_unescape, term[1:end])


_ESCAPE = re.compile(r"\\(?:u([0-9A-Fa-f]{4})|U([0-9A-Fa-f]{8})|(.))")
_CHARS = {"t": "\t", "b": "\b", "n": "\n", "r": "\r", "f": "\f", '"': '"', "'": "'", "\\": "\\"}


def _unescape(m: re.Match[str]) -> str:
    """One N-Triples escape sequence as its character."""
    code = m.group(1) or m.group(2)
    if code:
        return chr(int(code, 16))
    return _CHARS.get(m.group(3), m.group(0))
