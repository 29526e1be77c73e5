"""What a PLM integrator gets from the JSON-LD export, before and after the generated context.

    python bench/jsonld_measure.py [PROGRAM.stp]

Loads the program (default: the shipped example) and exports it as JSON-LD two
ways: "before", rdflib's serializer with the prefixes-only context (what the
export did up to issue 10, rebuilt here), and "after", ``export --format
jsonld`` (and ``jsonld-tree``). For each it prints the size, how many
``rdf:List``s come out as ``rdf:first``/``rdf:rest`` nodes instead of JSON
arrays, and what a JavaScript program that reads and writes the document back
(``JSON.stringify(JSON.parse(text))``, which writes the number 2.0 as ``2``)
does to the REAL values: how many ``xsd:double`` literals the document gives
after that round trip, and how many became ``xsd:integer``.
"""

from __future__ import annotations

import json
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pyoxigraph as ox
import rdflib

import stepnc_graph as sg
from stepnc_graph.export import canonical_quads
from stepnc_graph.generators.jsonld import context
from stepnc_graph.naming import Naming

HERE = Path(__file__).resolve().parent
XSD = "http://www.w3.org/2001/XMLSchema#"
RDF_FIRST = "http://www.w3.org/1999/02/22-rdf-syntax-ns#first"
RDF_REST = "http://www.w3.org/1999/02/22-rdf-syntax-ns#rest"


def before(store: sg.api.GraphStore, graph: str) -> bytes:
    """The export as it was: rdflib's JSON-LD serializer, a context of prefixes only."""

    def term(t: Any) -> Any:
        if isinstance(t, ox.BlankNode):
            return rdflib.BNode(t.value)
        if isinstance(t, ox.Literal):
            return rdflib.Literal(t.value, datatype=rdflib.URIRef(t.datatype.value))
        return rdflib.URIRef(t.value)

    g = rdflib.Graph(identifier=rdflib.URIRef(graph))
    for q in canonical_quads(store, graph):
        g.add((term(q.subject), term(q.predicate), term(q.object)))
    return g.serialize(format="json-ld", context=context(Naming()), auto_compact=True).encode("utf-8")


def javascript_round_trip(data: bytes) -> str:
    """``JSON.stringify(JSON.parse(data))``: a JavaScript number that is whole is written without '.0'."""

    def js(value: Any) -> Any:
        if isinstance(value, float) and value.is_integer() and abs(value) < 1e21:
            return int(value)
        if isinstance(value, list):
            return [js(v) for v in value]
        if isinstance(value, dict):
            return {k: js(v) for k, v in value.items()}
        return value

    return json.dumps(js(json.loads(data)))


def datatypes(text: str) -> Counter[str]:
    ds = rdflib.Dataset()
    ds.parse(data=text, format="json-ld")
    return Counter(str(o.datatype).removeprefix(XSD) for _, _, o, _ in ds.quads() if isinstance(o, rdflib.Literal)
                   and o.datatype is not None)


def chained_lists(data: bytes, heads: set[str]) -> int:
    """Lists (by their first cell, ``heads``: canonical labels) written as ``rdf:first``/``rdf:rest``
    nodes instead of a JSON array: the head is a node of its own with an ``rdf:first`` key."""
    chained: set[str] = set()

    def walk(value: Any) -> None:
        if isinstance(value, dict):
            if any(k in ("rdf:first", RDF_FIRST) for k in value) and str(value.get("@id", ""))[2:] in heads:
                chained.add(value["@id"])
            for v in value.values():
                walk(v)
        elif isinstance(value, list):
            for v in value:
                walk(v)

    walk(json.loads(data))
    return len(chained)


def main() -> None:
    program = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parent / "examples" / "shaft_two_setups.stp"
    with sg.open_store(memory=True) as store:
        [r] = sg.load(store, [program], lenient=True)
        reals = sum(1 for q in store.quads(r.graph) if isinstance(q.object, ox.Literal)
                    and q.object.datatype.value == XSD + "double")
        quads = list(canonical_quads(store, r.graph))
        cells = {q.subject.value for q in quads if q.predicate.value == RDF_FIRST}
        heads = cells - {q.object.value for q in quads if q.predicate.value == RDF_REST}
        print(f"{program.name}: {r.instances} instances, {r.triples} triples, {reals} REAL (xsd:double) values, "
              f"{len(heads)} lists")
        print(f"{'export':<22}{'bytes':>9}{'lists as chains':>16}{'doubles after JS':>18}{'became integer':>16}"
              f"{'cpu s':>8}")
        for name, make in (("before (rdflib)", lambda: before(store, r.graph)),
                           ("jsonld", lambda: sg.export(store, "jsonld", r.graph)),
                           ("jsonld-tree", lambda: sg.export(store, "jsonld-tree", r.graph))):
            cpu = time.process_time()
            data = make()
            cpu = time.process_time() - cpu
            after = datatypes(javascript_round_trip(data))
            print(f"{name:<22}{len(data):>9}{chained_lists(data, heads):>16}{after['double']:>18}"
                  f"{reals - after['double']:>16}{cpu:>8.3f}")


if __name__ == "__main__":
    main()
