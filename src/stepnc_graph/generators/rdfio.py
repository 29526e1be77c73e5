"""Byte-stable Turtle for generated graphs."""

from __future__ import annotations

from rdflib import Graph


def stable_turtle(graph: Graph) -> str:
    """Serialise ``graph`` as Turtle with a stable order of statements.

    rdflib's ``longturtle`` sorts subjects and predicates and writes
    collections and other single-use blank nodes inline, so equal graphs give
    equal text (checked by ``tests/test_build.py``).
    """
    text = graph.serialize(format="longturtle")
    return text if text.endswith("\n") else text + "\n"
