"""JSON-LD for PLM integrators: export with the generated context, and import.

**Export.** A program graph is written as JSON-LD 1.1 compacted with the terms of
``ontology/context.jsonld`` (see :mod:`stepnc_graph.generators.context`): short
type-scoped keys, lists as arrays, references relative to ``@base`` (the graph's
instance prefix, so ``#30`` is ``"i30"``), enumeration items by name, and every
REAL as its exact lexical form in a string coerced to ``xsd:double``. The
document embeds the part of the context it uses, so a consumer needs nothing
else and no network. ``tree=True`` writes the same graph as a readable tree:
each instance embedded once, under the referrer nearest the project (breadth
first: project -> workplans -> workingsteps -> operation, feature -> tool ...),
referred to by ``@id`` everywhere else.

The compaction is written here rather than run through a JSON-LD processor's
``compact``: the output must be deterministic (the canonical order of
:func:`stepnc_graph.exporting.exporter.canonical_quads`, no blank node labels) and fast on
large programs, and the shape is known (the loader's graphs). Its correctness
is checked the other way round: the tests expand every export with a JSON-LD
processor and compare with the store's quads.

**Import** is :mod:`stepnc_graph.loading.jsonld`: Oxigraph's JSON-LD 1.1 processor, which
cannot load a document, reads it; contexts are never fetched (the shipped one, named by
:data:`~stepnc_graph.core.naming.CONTEXT_IRI`, is served from the installed file), and
nothing JSON-LD would silently drop is loaded without an error.
"""

from __future__ import annotations

import json
import re
from collections import defaultdict, deque
from collections.abc import Iterable, Iterator
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.naming import CONTEXT_IRI, instance_prefix
from stepnc_graph.vocabulary.jsonld_context import PLAIN, Context, TermDef, shipped_context

RDF = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
XSD = "http://www.w3.org/2001/XMLSchema#"
RDF_TYPE, RDF_FIRST, RDF_REST, RDF_NIL = RDF + "type", RDF + "first", RDF + "rest", RDF + "nil"
XSD_STRING, XSD_INTEGER, XSD_BOOLEAN = XSD + "string", XSD + "integer", XSD + "boolean"
#: integers a JavaScript number holds exactly; larger ones are written as strings
_SAFE_INTEGER = 2**53 - 1
_CANONICAL_INTEGER = re.compile(r"-?(0|[1-9][0-9]*)")
#: a relative reference that resolves by appending to a base ending in '/': no scheme, no dot segments
_SIMPLE_PATH = re.compile(r"[A-Za-z0-9_~%!$&'()*+,;=-][A-Za-z0-9_~%!$&'()*+,;=./@-]*")


# -- export -------------------------------------------------------------------------------------


Term = ox.NamedNode | ox.BlankNode | ox.Literal


class _Graph:
    """One graph's triples, by subject, in the order given (the canonical export order)."""

    def __init__(self) -> None:
        self.props: dict[Term, dict[str, list[Term]]] = {}
        self.used: dict[ox.BlankNode, int] = defaultdict(int)

    def add(self, s: Term, p: str, o: Term) -> None:
        self.props.setdefault(s, {}).setdefault(p, []).append(o)
        if isinstance(o, ox.BlankNode):
            self.used[o] += 1

    def list_items(self, head: Term, cells: set[Term] | None = None) -> list[Term] | None:
        """The members of the well-formed ``rdf:List`` starting at ``head``, else None; its cells
        are added to ``cells``."""
        items: list[Term] = []
        node = head
        seen: set[Term] = set()
        while not (isinstance(node, ox.NamedNode) and node.value == RDF_NIL):
            p = self.props.get(node)
            if (not isinstance(node, ox.BlankNode) or node in seen or p is None or self.used[node] != 1
                    or set(p) != {RDF_FIRST, RDF_REST} or len(p[RDF_FIRST]) != 1 or len(p[RDF_REST]) != 1):
                return None
            seen.add(node)
            items.append(p[RDF_FIRST][0])
            node = p[RDF_REST][0]
        if cells is not None:
            cells.update(seen)
        return items


class _Writer:
    """Compacts one graph's triples with the shipped context."""

    def __init__(self, ctx: Context, g: _Graph, base: str | None, tree: bool) -> None:
        self.ctx = ctx
        self.g = g
        self.base = base
        self.types_used: set[str] = set()
        self.embedded: set[Term] = set()  # nodes written (inside another node or at the top)
        self.owner: dict[Term, Term] = self._tree_owners() if tree else {}

    # -- IRIs ----------------------------------------------------------------------------------

    def iri(self, node: Term) -> str:
        """How a node is named in ``@id`` position: relative to the base, a compact IRI, or absolute."""
        if isinstance(node, ox.BlankNode):
            return f"_:{node.value}"
        value = node.value
        if self.base is not None and value.startswith(self.base):
            rest = value[len(self.base):]
            if _SIMPLE_PATH.fullmatch(rest) and ":" not in rest.split("/")[0] and not any(
                    segment in (".", "..") for segment in rest.split("/")):
                return rest
        return self.ctx.compact(value)

    # -- nodes ---------------------------------------------------------------------------------

    def node(self, subject: Term, named: bool = True) -> dict[str, Any]:
        """The node object of ``subject`` (without ``@id`` for an embedded blank node)."""
        self.embedded.add(subject)
        props = self.g.props.get(subject, {})
        out: dict[str, Any] = {"@id": self.iri(subject)} if named else {}
        types = [t for t in props.get(RDF_TYPE, []) if isinstance(t, ox.NamedNode)]
        written = sorted(self.ctx.class_terms.get(t.value) or self.ctx.compact(t.value) for t in types)
        terms: dict[str, TermDef] = {}
        for name in written:  # type-scoped contexts apply in this (lexicographic) order
            if name in self.ctx.scoped:
                self.types_used.add(name)
                terms.update(self.ctx.scoped[name])
        if written:
            out["@type"] = written[0] if len(written) == 1 else written
        by_iri: dict[str, str] = {}
        ambiguous: set[str] = set()
        for name, term in terms.items():
            if term.iri in by_iri:
                ambiguous.add(term.iri)
            by_iri[term.iri] = name
        order = {name: i for i, name in enumerate(terms)}
        entries: list[tuple[tuple[int, int, str], str, Any]] = []
        for predicate, values in props.items():
            if predicate == RDF_TYPE:
                values = [v for v in values if not isinstance(v, ox.NamedNode)]
                if not values:
                    continue
            short = by_iri.get(predicate) if predicate not in ambiguous else None
            value = self.values(subject, values, terms[short]) if short is not None else None
            if short is None or value is None:  # no term, or values the term cannot carry
                key, value = self.ctx.compact(predicate), self.values(subject, values, PLAIN)
                entries.append(((1, 0, key), key, value))
            else:
                entries.append(((0, order[short], ""), short, value))
        out.update((name, value) for _, name, value in sorted(entries, key=lambda e: e[0]))
        return out

    def values(self, subject: Term, values: list[Term], term: TermDef) -> Any:
        """The JSON value of a key; None when ``term``'s container cannot hold them (then a compact IRI key)."""
        if term.container == "@list":
            if len(values) != 1:
                return None
            items = self.list_of(values[0])
            if items is None:
                return None
            self.consume(values[0])
            return [self.member(subject, v, term) for v in items]
        out = [self.value(subject, v, term) for v in values]
        return out[0] if len(out) == 1 and term.container != "@set" else out

    def list_of(self, node: Term) -> list[Term] | None:
        """The members of the list ``node`` heads (``rdf:nil``: none), or None when it is no list."""
        if isinstance(node, ox.NamedNode) and node.value == RDF_NIL:
            return []
        if isinstance(node, ox.BlankNode) and node not in self.embedded:
            return self.g.list_items(node)
        return None

    def consume(self, head: Term) -> None:
        """Mark the cells of the list at ``head`` written (as an array)."""
        self.g.list_items(head, self.embedded)

    def member(self, subject: Term, node: Term, term: TermDef) -> Any:
        """A member of a list under a ``@list`` term: a nested list is a nested array (JSON-LD 1.1)."""
        items = self.list_of(node)
        if items is not None:
            self.consume(node)
            return [self.member(subject, v, term) for v in items]
        return self.value(subject, node, term)

    def value(self, subject: Term, node: Term, term: TermDef) -> Any:
        if isinstance(node, ox.Literal):
            return self.literal(node, term)
        items = self.list_of(node)
        if items is not None:
            self.consume(node)
            return {"@list": [self.value(subject, v, term) for v in items]}
        if isinstance(node, ox.BlankNode):
            if self.g.used[node] == 1 and node in self.g.props and node not in self.embedded:
                return self.node(node, named=False)
        elif self.owner.get(node) == subject and node not in self.embedded:
            return self.node(node)
        if term.type == "@vocab" and isinstance(node, ox.NamedNode) and node.value in term.items:
            return term.items[node.value]
        name = self.iri(node)
        return name if term.type == "@id" else {"@id": name}

    def literal(self, lit: ox.Literal, term: TermDef) -> Any:
        lexical, datatype = lit.value, lit.datatype.value
        if lit.language:
            return {"@value": lexical, "@language": lit.language}
        if datatype == XSD_INTEGER and _CANONICAL_INTEGER.fullmatch(lexical) and abs(int(lexical)) <= _SAFE_INTEGER \
                and term.type in (None, XSD_INTEGER):
            return int(lexical)
        if term.type == datatype:
            return lexical
        if term.type is None:
            if datatype == XSD_STRING:
                return lexical
            if datatype == XSD_BOOLEAN and lexical in ("true", "false"):
                return lexical == "true"
        if datatype == XSD_STRING:
            return {"@value": lexical}
        return {"@value": lexical, "@type": self.ctx.compact(datatype)}

    # -- the tree ------------------------------------------------------------------------------

    def _tree_owners(self) -> dict[Term, Term]:
        """For each named node: the node it is written inside (breadth first from the roots)."""
        named = [s for s in self.g.props if isinstance(s, ox.NamedNode)]
        referenced = {o for s in named for p, vs in self.g.props[s].items() if p != RDF_TYPE for o in self._refs(vs)}
        project = self.ctx.expand("stepnc:project")
        projects = [s for s in named if any(t.value == project for t in self.g.props[s].get(RDF_TYPE, [])
                                            if isinstance(t, ox.NamedNode))]
        roots = projects or [s for s in named if s not in referenced]
        owner: dict[Term, Term] = {}
        placed: set[Term] = set(roots)
        queue: deque[Term] = deque(roots)
        while queue:
            subject = queue.popleft()
            for predicate, values in self.g.props.get(subject, {}).items():
                if predicate == RDF_TYPE:
                    continue
                for o in self._refs(values):
                    if o in self.g.props and o not in placed:
                        placed.add(o)
                        owner[o] = subject
                        queue.append(o)
        return owner

    def _refs(self, values: list[Term]) -> Iterator[Term]:
        """The named nodes among ``values`` and inside the lists they hold, in order."""
        for node in values:
            if isinstance(node, ox.NamedNode):
                yield node
            elif isinstance(node, ox.BlankNode):
                items = self.g.list_items(node)
                if items is not None:
                    yield from self._refs(items)

    def graph(self) -> list[dict[str, Any]]:
        """The top-level nodes: named subjects in order (in a tree: those no one embeds), then
        blank nodes no one refers to, then whatever is left (blank cycles): every triple, once."""
        out = []
        for subject in self.g.props:
            if isinstance(subject, ox.NamedNode) and subject not in self.embedded and subject not in self.owner:
                out.append(self.node(subject))
        for subject in self.g.props:
            if isinstance(subject, ox.BlankNode) and self.g.used[subject] == 0 and subject not in self.embedded:
                out.append(self.node(subject))
        for subject in self.g.props:
            if subject not in self.embedded:
                out.append(self.node(subject))
        return out


def document(quads: Iterable[ox.Quad], graph: str | None, tree: bool = False) -> dict[str, Any]:
    """The JSON-LD document of ``graph``'s quads (``None``: of every graph given: a dataset).

    A graph's document is ``{"@context", "@id": graph, "@graph": [...]}``: the
    named graph, with ``@base`` its instance prefix.
    """
    ctx = shipped_context()
    graphs: dict[str | None, _Graph] = {}
    for q in quads:
        name = q.graph_name.value if isinstance(q.graph_name, ox.NamedNode) else None
        graphs.setdefault(name, _Graph()).add(q.subject, q.predicate.value, q.object)  # type: ignore[arg-type]
    used: set[str] = set()

    def named(name: str, g: _Graph, own_context: bool) -> dict[str, Any]:
        base = instance_prefix(name) if _hierarchical(name) else None
        writer = _Writer(ctx, g, base, tree)
        nodes = writer.graph()
        used.update(writer.types_used)
        head: dict[str, Any] = {"@context": {"@base": base}} if own_context and base else {}
        return {**head, "@id": name, "@graph": nodes}

    if graph is not None:
        body = named(graph, graphs.get(graph, _Graph()), False)
        base = instance_prefix(graph) if _hierarchical(graph) else None
        subset = ctx.subset(used)
        local = {"@version": subset.pop("@version"), **({"@base": base} if base else {}), **subset}
        return {"@context": local, **body}
    top: list[dict[str, Any]] = []
    if None in graphs:
        writer = _Writer(ctx, graphs[None], None, tree)
        top.extend(writer.graph())
        used.update(writer.types_used)
    top.extend(named(name, g, True) for name, g in graphs.items() if name is not None)
    return {"@context": ctx.subset(used), "@graph": top}


def _hierarchical(iri: str) -> bool:
    """Whether relative references resolve against this graph's instance prefix as plain appends."""
    prefix = instance_prefix(iri)
    return prefix.startswith(("http://", "https://")) and prefix.endswith("/") and "?" not in prefix \
        and "#" not in prefix


def dumps(doc: dict[str, Any]) -> bytes:
    """The document as UTF-8 JSON, keys in the order written: the context laid out as the shipped
    file is (a line per term), the data two-space indented."""
    from stepnc_graph.generators.context import dumps as context_text

    body = json.dumps({k: v for k, v in doc.items() if k != "@context"}, indent=2, ensure_ascii=False)
    head = context_text({"@context": doc["@context"]})
    return (head[:-len("\n}\n")] + ",\n" + body[len("{\n"):] + "\n").encode("utf-8")


def export_jsonld(quads: Iterable[ox.Quad], graph: str | None, tree: bool = False) -> bytes:
    """``document`` as bytes: what ``export --format jsonld`` (``jsonld-tree``) writes."""
    return dumps(document(quads, graph, tree))


__all__ = ["CONTEXT_IRI", "Context", "document", "dumps", "export_jsonld", "shipped_context"]
