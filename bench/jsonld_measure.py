"""What a PLM integrator gets from the JSON-LD export, before and after the generated context.

    python bench/jsonld_measure.py [PROGRAM.stp] [--size 20000]

Loads the program (default: the shipped example) and exports it as JSON-LD two
ways: "before", rdflib's serializer with the prefixes-only context (what the
export did up to issue 10, rebuilt here), and "after", ``export --format
jsonld`` (and ``jsonld-tree``). For each it prints the size, how many
``rdf:List``s come out as ``rdf:first``/``rdf:rest`` nodes instead of JSON
arrays, and what a JavaScript program that reads and writes the document back
(``JSON.stringify(JSON.parse(text))``, which writes the number 2.0 as ``2``)
does to the REAL values: how many ``xsd:double`` literals the document gives
after that round trip, and how many became ``xsd:integer``.

``--size N`` then times, on a generated N-instance program (``bench/generate.py``),
the exports (N-Triples and Part 21 as references, JSON-LD, JSON-LD tree; median
of 3, CPU and wall seconds) and loading the JSON-LD export back next to loading
the Part 21 file (one run each).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pyoxigraph as ox
import rdflib

import stepnc_graph as sg
from stepnc_graph.exporting.exporter import canonical_quads
from stepnc_graph.generators.context import context
from stepnc_graph.core.naming import Naming

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


def timed(run: Any, repeat: int) -> tuple[float, float, Any]:
    """Median CPU and wall seconds of ``repeat`` runs, and the last result."""
    cpu, wall, out = [], [], None
    for _ in range(repeat):
        c, w = time.process_time(), time.perf_counter()
        out = run()
        cpu.append(time.process_time() - c)
        wall.append(time.perf_counter() - w)
    return statistics.median(cpu), statistics.median(wall), out


def scale(size: int) -> None:
    """Export and load times of JSON-LD next to N-Triples and Part 21 on a generated program."""
    sys.path.insert(0, str(HERE))
    from generate import write  # bench/generate.py

    work = Path(tempfile.mkdtemp(prefix="stepnc-jsonld-"))
    program = work / f"turning_{size}.stp"
    write(size, program)
    with sg.open_store(memory=True) as store:
        [r] = sg.load(store, [program])
        print(f"\n{program.name}: {r.instances} instances, {r.triples} triples")
        for fmt in ("nt", "p21", "jsonld", "jsonld-tree"):
            cpu, wall, data = timed(lambda fmt=fmt: sg.export(store, fmt, r.graph), 3)
            print(f"export {fmt:<12} {len(data):>10} bytes  cpu {cpu:6.2f} s  wall {wall:6.2f} s")
            if fmt == "jsonld":
                (work / "program.jsonld").write_bytes(data)
        for name, path in (("Part 21", program), ("JSON-LD", work / "program.jsonld")):
            cpu, wall, _ = timed(lambda path=path: sg.load(store, [path], base_iri=f"{r.graph}-{path.suffix[1:]}"), 1)
            print(f"load {name:<14} {path.stat().st_size:>10} bytes  cpu {cpu:6.2f} s  wall {wall:6.2f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("program", nargs="?", type=Path, default=HERE.parent / "examples" / "shaft_two_setups.stp")
    ap.add_argument("--size", type=int, default=None, help="also time a generated program of this many instances")
    args = ap.parse_args()
    program = args.program
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
    if args.size:
        scale(args.size)


if __name__ == "__main__":
    main()
