"""Check the shipped vocabulary with real OWL tools: the OWL API's OWL 2 DL profile checker and HermiT.

Developer and CI tool (``tests/test_owl_dl.py`` runs the same functions); not used at run time.

* The profile checker is the OWL API of Debian's ``libowlapi-java`` (``/usr/share/java``), run by
  ``tools/OwlProfileCheck.java`` as a single-file source program (needs a JDK: ``java`` compiles it).
* HermiT is the jar the ``owlready2`` package ships (PyPI), run through its command line: ``-U``
  lists the unsatisfiable classes, ``-k`` decides consistency. owlready2's own reasoning entry point
  also classifies every instance, which takes minutes on a few programs; the jar is the same.

Nothing here reads the network: the vocabulary's ``owl:imports`` are resolved to the files of
``ontology/`` (the profile checker) or dropped after merging every file into one graph (HermiT).

Programs are given to HermiT as the store holds them (the file's graph and its derived layer), read
the way OWL 2 DL reads them: a LOGICAL UNKNOWN, ``"UNKNOWN"^^p21:logicalUnknown`` in the store, is
the string "UNKNOWN", which the vocabulary defines that datatype to hold (OWL 2 DL admits no literal
of a datatype defined in the ontology, and HermiT refuses one).

    python tools/owl_dl.py [PROGRAM ...]   # profile violations by kind, unsatisfiable classes,
                                           # consistency of the vocabulary with the programs
"""

from __future__ import annotations

import importlib.util
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from rdflib import OWL, RDF, XSD, Dataset, Graph, Literal, URIRef

ROOT = Path(__file__).resolve().parent.parent
ONTOLOGY = ROOT / "ontology"
CHECKER = Path(__file__).resolve().parent / "OwlProfileCheck.java"
JAVA_DIR = Path("/usr/share/java")
#: The OWL API jar and what it needs at run time, as Debian installs them (libowlapi-java's depends).
OWLAPI_JARS = ("owlapi-distribution", "atinject-jsr330-api", "caffeine", "commons-codec", "commons-io",
               "commons-logging", "commons-rdf-api", "commons-rdf-simple", "guava", "hppcrt", "httpclient",
               "httpcore", "jackson-annotations", "jackson-core", "jackson-databind", "jsonld-java", "jsr305",
               "slf4j-api", "slf4j-nop", "xz")
INSTALL_HINT = ("apt-get install libowlapi-java default-jdk-headless (Debian; .ci/run does this in CI) and "
                "pip install owlready2 (in the test extra)")
LOGICAL_UNKNOWN = URIRef("https://w3id.org/stepnc-graph/p21#logicalUnknown")
VOCABULARY_GRAPH = "https://w3id.org/stepnc-graph/iso14649"


class ToolMissing(RuntimeError):
    """A tool this check needs is not installed; the message says which and how to install it."""


@dataclass(frozen=True)
class Violation:
    ontology: str
    kind: str
    text: str


@dataclass(frozen=True)
class Reasoned:
    """What HermiT said: ``consistent``, the ``unsatisfiable`` classes (with ``-U``), the time taken."""

    consistent: bool
    unsatisfiable: tuple[str, ...]
    wall: float
    cpu: float
    output: str


# -- tools ------------------------------------------------------------------------------------------


def java() -> str:
    found = shutil.which("java")
    if found is None:
        raise ToolMissing(f"no java on PATH: {INSTALL_HINT}")
    return found


def owlapi_classpath(java_dir: Path = JAVA_DIR) -> str:
    """The class path of the Debian OWL API, or :class:`ToolMissing`."""
    if not (java_dir / "owlapi-distribution.jar").is_file():
        raise ToolMissing(f"the OWL API is not installed ({java_dir}/owlapi-distribution.jar): {INSTALL_HINT}")
    jars = [java_dir / f"{name}.jar" for name in OWLAPI_JARS]
    jars += sorted(java_dir.glob("rdf4j-*.jar"))
    return ":".join(str(j) for j in jars if j.is_file())


def hermit_classpath() -> str:
    """The class path of the HermiT jar owlready2 ships, or :class:`ToolMissing`."""
    spec = importlib.util.find_spec("owlready2")
    if spec is None or spec.origin is None:
        raise ToolMissing(f"owlready2 (which ships HermiT) is not installed: {INSTALL_HINT}")
    folder = Path(spec.origin).parent / "hermit"
    if not (folder / "HermiT.jar").is_file():
        raise ToolMissing(f"owlready2 has no hermit/HermiT.jar in {folder}")
    return f"{folder}:{folder / 'HermiT.jar'}"


def _cpu_of_children() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


# -- the profile checker ----------------------------------------------------------------------------


def ontology_files(directory: Path = ONTOLOGY) -> list[tuple[str, Path]]:
    """(ontology IRI, file) of every ``*.ttl`` in ``directory`` that declares an ontology."""
    out = []
    for path in sorted(directory.glob("*.ttl")):
        g = Graph().parse(path, format="turtle")
        out.extend((str(o), path) for o in g.subjects(RDF.type, OWL.Ontology))
    return out


def profile_violations(directory: Path = ONTOLOGY, timeout: float = 300) -> list[Violation]:
    """The OWL 2 DL profile violations the OWL API finds in each ontology of ``directory`` (with its
    imports) and in the union of all (ontology ``urn:x-stepnc-graph:all-ontologies``)."""
    if shutil.which("javac") is None:  # java runs a source file with the JDK's compiler
        raise ToolMissing(f"no JDK (javac) to run {CHECKER.name}: {INSTALL_HINT}")
    command = [java(), "-cp", owlapi_classpath(), str(CHECKER),
               *(f"{iri}={path}" for iri, path in ontology_files(directory))]
    done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    if done.returncode != 0 or "OWL 2 DL profile violations:" not in done.stderr:
        raise RuntimeError(f"the profile checker failed (exit {done.returncode}): {done.stderr[-2000:]}")
    out = []
    for line in done.stdout.splitlines():
        ontology, kind, text = line.split("\t", 2)
        out.append(Violation(ontology, kind, text))
    return out


# -- HermiT -----------------------------------------------------------------------------------------


def vocabulary_graph(directory: Path = ONTOLOGY) -> Graph:
    """Every ``*.ttl`` of ``directory`` in one graph, without ``owl:imports`` (all are here already;
    HermiT would fetch them from the web)."""
    g = Graph()
    for path in sorted(directory.glob("*.ttl")):
        g.parse(path, format="turtle")
    g.remove((None, OWL.imports, None))
    return g


def dl_reading(quads: Iterable[tuple[object, object, object, object]], into: Graph) -> Graph:
    """Add the triples of ``quads`` to ``into`` as OWL 2 DL reads them: ``"UNKNOWN"^^p21:logicalUnknown``
    as the string it is defined to be. The vocabulary graph of a store is left out (``into`` has it)."""
    for s, p, o, c in quads:
        if str(c) == VOCABULARY_GRAPH:
            continue
        if isinstance(o, Literal) and o.datatype == LOGICAL_UNKNOWN:
            o = Literal(str(o), datatype=XSD.string)
        into.add((s, p, o))  # type: ignore[arg-type]
    return into


def program_quads(paths: Sequence[str | Path]) -> Dataset:
    """The programs loaded (leniently: damaged files load with findings) into a throw-away store:
    each file's graph and derived layer, as N-Quads read back into rdflib."""
    import stepnc_graph as sg

    with sg.open_store(memory=True) as store:
        sg.load(store, [str(p) for p in paths], lenient=True)
        nquads = sg.export(store, "nq")
    ds = Dataset()
    ds.parse(data=nquads, format="nquads")
    return ds


def hermit(graph: Graph, *actions: str, timeout: float = 900) -> Reasoned:
    """Run HermiT on ``graph`` with ``actions`` (``-k`` consistency, ``-U`` unsatisfiable classes)."""
    with tempfile.TemporaryDirectory(prefix="stepnc-owl-") as tmp:
        path = Path(tmp) / "input.nt"
        graph.serialize(path, format="nt", encoding="utf-8")
        command = [java(), "-cp", hermit_classpath(), "org.semanticweb.HermiT.cli.CommandLine", *actions,
                   path.as_uri()]
        wall, cpu = time.monotonic(), _cpu_of_children()
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
        wall, cpu = time.monotonic() - wall, _cpu_of_children() - cpu
    text = done.stdout + done.stderr
    if "InconsistentOntologyException" in text:
        return Reasoned(False, (), wall, cpu, text)
    if done.returncode != 0:
        raise RuntimeError(f"HermiT failed (exit {done.returncode}): {text[-2000:]}")
    unsatisfiable: list[str] = []
    if "-U" in actions:
        block = done.stdout.split("Classes equivalent to 'owl:Nothing':", 1)[1]
        for line in block.splitlines():
            name = line.strip()
            if line.startswith("\t") and name and name != "owl:Nothing":
                unsatisfiable.append(name.strip("<>"))
    return Reasoned(True, tuple(sorted(unsatisfiable)), wall, cpu, text)


# -- the report -------------------------------------------------------------------------------------


def main(argv: list[str]) -> int:
    try:
        violations = profile_violations()
    except ToolMissing as e:
        print(f"profile check: skipped, {e}")
    else:
        per_ontology = Counter(v.ontology for v in violations)
        union = [v for v in violations if v.ontology == "urn:x-stepnc-graph:all-ontologies"]
        print(f"OWL 2 DL profile: {len(union)} violation(s) in the union of the ontologies "
              f"({', '.join(f'{n} {k}' for k, n in Counter(v.kind for v in union).most_common()) or 'none'}); "
              f"{sum(n for o, n in per_ontology.items() if not o.startswith('urn:'))} in the ontologies "
              "checked one by one with their imports")
    vocabulary = vocabulary_graph()
    try:
        tbox = hermit(vocabulary, "-U")
    except ToolMissing as e:
        print(f"HermiT: skipped, {e}")
        return 0
    except RuntimeError as e:
        print(f"HermiT refuses the vocabulary: {str(e)[-600:]}")
        return 1
    print(f"HermiT: {len(tbox.unsatisfiable)} unsatisfiable class(es) {list(tbox.unsatisfiable)} "
          f"({tbox.wall:.1f} s, {tbox.cpu:.1f} s CPU)")
    if argv:
        data = dl_reading(program_quads(argv).quads((None, None, None, None)), Graph() + vocabulary)
        result = hermit(data, "-k")
        print(f"HermiT: vocabulary and {len(argv)} program(s), {len(data)} triples: "
              f"{'consistent' if result.consistent else 'INCONSISTENT'} ({result.wall:.1f} s, {result.cpu:.1f} s CPU)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
