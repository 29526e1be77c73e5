"""The shipped vocabulary with real OWL tools: OWL 2 DL by the OWL API's profile checker, no
unsatisfiable class and consistency with every program by HermiT (tools/owl_dl.py).

Needs Java with Debian's libowlapi-java and owlready2's HermiT jar; .ci/run installs them. Where
they are missing these tests skip, saying what to install.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from rdflib import Graph, URIRef

from conftest import FIXTURES, ROOT, SHARED

sys.path.insert(0, str(ROOT / "tools"))
import owl_dl  # noqa: E402

#: Programs with a reference to an instance of a class the attribute's range is disjoint from
#: (``validate`` reports each as "must be a ..."); with these the knowledge base is inconsistent.
WRONG_REFERENCES = {
    # #81 AXIS2_PLACEMENT_3D.axis: a CARTESIAN_POINT, not a direction (and its location a placement);
    # #87 GENERAL_PROFILE.its_profile: a CARTESIAN_POINT, not a bounded_curve
    "fail_seed_annex_d.stp": (81, 87),
    # #111 AXIS2_PLACEMENT_3D.location: itself, not a cartesian_point (and its axis a CARTESIAN_POINT);
    # #207 AXIS2_PLACEMENT_3D.location: a DIRECTION (and its ref_direction a CARTESIAN_POINT)
    "fail_seed_annex_e.stp": (111, 207),
}


def programs() -> list[Path]:
    """Every example, every fixture program and, where ../shared is present, every corpus program."""
    found = sorted((ROOT / "examples").glob("*.stp")) + sorted(FIXTURES.rglob("*.stp"))
    corpus = SHARED / "corpus" / "milling"
    if corpus.is_dir():
        found += sorted(p for p in corpus.iterdir() if p.suffix.lower() in (".stp", ".p21"))
    return found


@pytest.fixture(scope="module")
def vocabulary() -> Iterator[Graph]:
    try:
        owl_dl.java()
        owl_dl.hermit_classpath()
    except owl_dl.ToolMissing as e:
        pytest.skip(str(e))
    yield owl_dl.vocabulary_graph()


def test_vocabulary_is_owl2_dl() -> None:
    try:
        violations = owl_dl.profile_violations()
    except owl_dl.ToolMissing as e:
        pytest.skip(str(e))
    assert [(v.ontology, v.kind, v.text[:300]) for v in violations] == []
    checked = {iri for iri, _ in owl_dl.ontology_files()}
    assert len(checked) == 22 and "https://w3id.org/stepnc-graph/attribute" in checked
    assert "https://w3id.org/stepnc-graph/iso14649/edition/fdis2001" in checked  # the 2001 edition's own terms


def test_vocabulary_has_no_unsatisfiable_class(vocabulary: Graph) -> None:
    result = owl_dl.hermit(vocabulary, "-U")
    assert result.consistent and result.unsatisfiable == ()


def _instance(quad: tuple[object, ...], wrong: dict[str, tuple[int, ...]]) -> bool:
    """Whether ``quad`` is a triple about one of the ``wrong`` instances (in the file's graph or its
    derived layer)."""
    subject = str(quad[0])
    return any(subject == f"https://w3id.org/stepnc-graph/data/{name}/i{n}" for name, ids in wrong.items()
               for n in ids)


def test_vocabulary_is_consistent_with_every_program(vocabulary: Graph) -> None:
    """All programs in one knowledge base (each has its own IRIs), without the two wrong references."""
    paths = programs()
    assert len(paths) >= 14
    quads = [q for q in owl_dl.program_quads(paths).quads((None, None, None, None))
             if not _instance(q, WRONG_REFERENCES)]
    data = owl_dl.dl_reading(quads, Graph() + vocabulary)
    result = owl_dl.hermit(data, "-k")
    assert result.consistent, result.output[-1500:]


@pytest.mark.parametrize("name", sorted(WRONG_REFERENCES))
def test_reasoner_finds_the_wrong_reference(vocabulary: Graph, name: str) -> None:
    """The damaged fixtures are inconsistent, and only through the reference validate also reports."""
    [path] = [p for p in programs() if p.name == name]
    quads = list(owl_dl.program_quads([path]).quads((None, None, None, None)))
    assert not owl_dl.hermit(owl_dl.dl_reading(quads, Graph() + vocabulary), "-k").consistent
    for n in WRONG_REFERENCES[name]:  # each of them alone makes it inconsistent
        rest = [q for q in quads if not _instance(q, {name: tuple(m for m in WRONG_REFERENCES[name] if m != n)})]
        assert not owl_dl.hermit(owl_dl.dl_reading(rest, Graph() + vocabulary), "-k").consistent, n


def test_dl_reading_of_logical_unknown() -> None:
    """UNKNOWN is kept typed in the store (round trip) and read as its defined string by a reasoner."""
    from rdflib import XSD, Literal

    unknown = Literal("UNKNOWN", datatype=owl_dl.LOGICAL_UNKNOWN)
    s, p = URIRef("urn:x:s"), URIRef("urn:x:p")
    g = owl_dl.dl_reading([(s, p, unknown, URIRef("urn:x:g")),
                           (s, p, Literal(1), URIRef(owl_dl.VOCABULARY_GRAPH))], Graph())
    assert set(g) == {(s, p, Literal("UNKNOWN", datatype=XSD.string))}


def test_missing_owl_api_is_a_stated_skip_reason(tmp_path: Path) -> None:
    """Without Debian's OWL API the profile test skips and says how to install it."""
    with pytest.raises(owl_dl.ToolMissing, match="apt-get install libowlapi-java"):
        owl_dl.owlapi_classpath(tmp_path)
