"""The shapes of EXPRESS supertype constraints (ISO 10303-11 9.2.5): an ABSTRACT entity's
instances belong to a subtype, and the operands of a ``ONEOF`` exclude each other. Part of
:class:`~stepnc_graph.generators.shacl.ShapesGenerator`, which writes them into a schema's graph."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rdflib import RDF, SH, BNode, Graph, Literal

from stepnc_graph.schema.model import Entity, SupertypeExpr

if TYPE_CHECKING:
    from stepnc_graph.generators.shacl import ShapesGenerator


def add_abstract(gen: ShapesGenerator, g: Graph, e: Entity) -> None:
    """An instance of an ABSTRACT entity must be an instance of one of its subtypes."""
    shape = gen.shapes[f"{e.name}-abstract"]
    g.add((shape, RDF.type, SH.NodeShape))
    g.add((shape, SH.targetClass, gen.n.declaration(e.name)))
    gen.annotate(g, shape, e.name, f"{e.name} ABSTRACT")
    g.add((shape, SH.message, Literal(f"{e.name} is ABSTRACT: an instance must be of one of its subtypes")))
    subs = gen.model.subtypes(e.name)
    if not subs:
        g.add((shape, SH["not"], gen.shapes[f"{e.name}-abstract-any"]))
        g.add((gen.shapes[f"{e.name}-abstract-any"], RDF.type, SH.NodeShape))
        return
    alternatives = []
    for s in subs:
        alt = BNode(f"abstract_{e.name}_{s}")
        g.add((alt, SH["class"], gen.n.declaration(s)))
        alternatives.append(alt)
    gen._list(g, shape, SH["or"], alternatives)


def add_oneof(gen: ShapesGenerator, g: Graph, e: Entity, expr: SupertypeExpr) -> None:
    """``ONEOF(a, b, c)``: an instance of ``a`` is of neither ``b`` nor ``c`` (each pair once).

    An operand ``(x ANDOR y)`` holds the instances of ``x`` or ``y``. An
    operand listed twice (``face_bound`` in topological_representation_item)
    is taken once: read literally it would exclude itgen.
    """
    for k, operands in enumerate(oneofs(expr), 1):
        for i, names in enumerate(operands[:-1]):
            later = [n for other in operands[i + 1:] for n in other]
            for first in names:
                shape = gen.shapes[f"{e.name}-oneof{k}-{first}"]
                g.add((shape, RDF.type, SH.NodeShape))
                g.add((shape, SH.targetClass, gen.n.declaration(first)))
                gen.annotate(g, shape, e.name, f"{e.name} SUPERTYPE OF {expr}")
                g.add((shape, SH.message, Literal(f"ONEOF in {e.name}: {first} excludes {', '.join(later)}")))
                alternatives = []
                for other in later:
                    alt = BNode(f"oneof_{e.name}_{first}_{other}")
                    g.add((alt, SH["class"], gen.n.declaration(other)))
                    alternatives.append(alt)
                inner = BNode(f"oneof_{e.name}_{first}")
                g.add((shape, SH["not"], inner))
                gen._list(g, inner, SH["or"], alternatives)


def oneofs(expr: SupertypeExpr) -> list[list[list[str]]]:
    """Each ONEOF in ``expr``: its operands, each the names whose instances belong to it."""
    out: list[list[list[str]]] = []
    if expr.op == "ONEOF":
        operands: list[list[str]] = []
        seen: set[str] = set()
        for o in expr.operands:
            if isinstance(o, SupertypeExpr) and o.op != "ANDOR":
                raise NotImplementedError("ONEOF over an AND or ONEOF operand")  # none in the shipped schemas
            names = [n for n in (o.names() if isinstance(o, SupertypeExpr) else [o]) if n not in seen]
            seen.update(names)
            if names:
                operands.append(names)
        out.append(operands)
    for o in expr.operands:
        if isinstance(o, SupertypeExpr):
            out.extend(oneofs(o))
    return out
