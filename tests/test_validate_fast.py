"""`validate FILE`'s fast path: what it leaves out of the load and of the checks changes nothing in the
report, and the cheaper forms it uses (class tests, the multi-typed test, the text scans before
the parse) answer exactly what the forms they replace answered."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pyoxigraph as ox
import pytest

from stepnc_graph import api
from stepnc_graph.validation import _validate_store, compile_shapes, shape_files, throwaway, validate

ROOT = Path(__file__).resolve().parent.parent
FIX = Path(__file__).parent / "fixtures"
FIXTURES = [ROOT / "examples" / "shaft_two_setups.stp", ROOT / "examples" / "shaft_damaged.stp",
            *sorted((FIX / "p21").glob("*.stp")), *sorted((FIX / "validate").glob("*.stp"))]


@pytest.fixture(autouse=True)
def _leave_out_at_any_size(monkeypatch: pytest.MonkeyPatch) -> None:
    """These small programs take the way a large one does: the attributes no check reads left out."""
    monkeypatch.setattr(throwaway, "HOLD_BYTES", 0)


def test_a_small_program_is_loaded_whole_while_what_the_checks_read_is_unknown(monkeypatch: pytest.MonkeyPatch,
                                                                              tmp_path: Path) -> None:
    """Below ``HOLD_BYTES`` no time goes into working out what the checks read (it would cost more
    than it saves): shapes of one's own load a small program whole, and at or above it leave out
    what no check reads. The shipped checks' answer comes from the build, so with them even a
    small program leaves it out (cheaper at every size)."""
    from stepnc_graph.loading import loader

    asked: list[frozenset[str] | None] = []
    real = loader.load_paths

    def recorded(*args: Any, **kwargs: Any) -> Any:
        asked.append(kwargs["reads"])
        return real(*args, **kwargs)

    monkeypatch.setattr(loader, "load_paths", recorded)
    monkeypatch.setattr(throwaway, "HOLD_BYTES", SHAFT.stat().st_size + 1)
    shipped = validate([SHAFT], lenient=True)
    own = [_own_shape(tmp_path)]
    small = validate([SHAFT], lenient=True, extra_shapes=own)
    monkeypatch.setattr(throwaway, "HOLD_BYTES", SHAFT.stat().st_size)
    held = validate([SHAFT], lenient=True, extra_shapes=own)
    assert asked[0] is not None and f"{STEPNC}placement.name" not in asked[0]
    assert asked[1] is None and asked[2] is not None
    assert [r.asdict() for r in held.results] == [r.asdict() for r in small.results]
    assert len(small.results) > len(shipped.results)


def test_what_the_shipped_checks_read_comes_from_the_build(monkeypatch: pytest.MonkeyPatch) -> None:
    """Working out what the checks read is some 50 ms of pattern matching over the shipped checks:
    the build does it once and stores the answer beside them, so validating a program with the
    shipped shapes does none of it; other shapes get it worked out here, once per process."""
    from stepnc_graph.validation import compiled, reads

    shipped = compile_shapes(shape_files())
    stored = shipped.reads()
    assert stored == (reads.properties_read(shipped.checks), reads.reads_positions(shipped.checks))
    calls: list[str] = []

    def refused(name: str) -> Any:
        def call(checks: object) -> None:
            calls.append(name)
            raise AssertionError(f"{name} worked out again")
        return call

    monkeypatch.setattr(compiled, "properties_read", refused("properties_read"))
    monkeypatch.setattr(compiled, "reads_positions", refused("reads_positions"))
    compiled._compiled.cache_clear()  # as in a fresh process: the shipped file read again
    try:
        fresh = compile_shapes(shape_files())
        assert fresh is not shipped and fresh.reads() == stored
        assert validate([SHAFT], lenient=True).checks_run > 100
    finally:
        compiled._compiled.cache_clear()
    assert calls == []


@pytest.mark.parametrize("program", FIXTURES, ids=lambda p: p.name)
def test_the_fast_path_reports_what_the_full_path_reports(program: Path) -> None:
    """``validate([file])`` (no derived layer, no position triples, the checks the mapping implies
    skipped) against the full load of the same file checked with every check and the same loader
    diagnostics: the same results, field by field, in the same order."""
    fast = validate([program], lenient=True)
    shapes = compile_shapes(shape_files())
    with api.open_store(memory=True) as store:
        [loaded] = api.load(store, [program], lenient=True, base_iri=fast.graphs[0])
        assert loaded.lines is None and loaded.derived_triples > 0  # the full load
        full = _validate_store(store, [loaded.graph], shapes, list(shapes.checks), {loaded.graph: loaded.diagnostics})
    assert full.checks_run > fast.checks_run
    assert [r.asdict() for r in fast.results] == [r.asdict() for r in full.results]


# -- the attributes no check reads ----------------------------------------------------------------------

SHAFT = ROOT / "examples" / "shaft_two_setups.stp"
STEPNC = "https://w3id.org/stepnc-graph/iso14649#"


def _shaft(tmp_path: Path, old: str, new: str) -> Path:
    text = SHAFT.read_text()
    assert old in text
    path = tmp_path / "shaft.stp"
    path.write_text(text.replace(old, new, 1))
    return path


def test_the_throwaway_graph_leaves_out_the_attributes_no_check_reads() -> None:
    """The shipped checks that run on a clean program read neither placement names nor point
    coordinates: ``validate FILE``'s load leaves them (and the coordinates' list cells) out."""
    from stepnc_graph.loading.loader import load_paths
    from stepnc_graph.validation.reads import properties_read

    shapes = compile_shapes(shape_files())
    reads = properties_read(list(shapes.checks))
    assert reads is not None and f"{STEPNC}placement.name" not in reads
    assert f"{STEPNC}axis2_placement_3d.axis" in reads
    counts = []
    for given in (None, reads):
        with api.open_store(memory=True) as store:
            [r] = load_paths(store, [SHAFT], lenient=True, derived=False, positions=False, reads=given)
            g = ox.NamedNode(r.graph)
            counts.append(len(store.oxigraph))
            names = store.oxigraph.query(f"ASK {{ ?s <{STEPNC}placement.name> ?n }}", default_graph=g)
            assert bool(names) is (given is None)
            assert store.oxigraph.query(f"ASK {{ ?s <{STEPNC}axis2_placement_3d.axis> ?n }}", default_graph=g)
    assert counts[1] < 0.85 * counts[0]


@pytest.mark.parametrize("old, new", [
    ("#201=CARTESIAN_POINT('ORIGIN',(0.,0.,0.));", "#201=CARTESIAN_POINT($,(0.,0.,0.));"),  # an unset mandatory name
    ("#201=CARTESIAN_POINT('ORIGIN',(0.,0.,0.));", "#201=CARTESIAN_POINT('ORIGIN',(0.,$,0.));"),  # an unset member
    ("#201=CARTESIAN_POINT('ORIGIN',(0.,0.,0.));", "#201=CARTESIAN_POINT('ORIGIN',(0.,0.,0.,1.));"),  # out of bounds
], ids=["unset-mandatory", "unset-member", "list-out-of-bounds"])
def test_the_attributes_left_out_come_back_with_the_checks_that_read_them(tmp_path: Path, old: str, new: str) -> None:
    """A program without the mapping's guarantees gets the checks it implies, and every attribute
    they read: the report of the full path, results included."""
    program = _shaft(tmp_path, old, new)
    fast = validate([program], lenient=True)
    shapes = compile_shapes(shape_files())
    with api.open_store(memory=True) as store:
        [loaded] = api.load(store, [program], lenient=True, base_iri=fast.graphs[0])
        full = _validate_store(store, [loaded.graph], shapes, list(shapes.checks), {loaded.graph: loaded.diagnostics})
    assert fast.results and [r.asdict() for r in fast.results] == [r.asdict() for r in full.results]


#: how an own check names the attribute: by its IRI, a prefixed name, or not at all (any
#: predicate but rdf:type, any predicate)
NAMINGS = {"iri": f"<{STEPNC}point.name>", "prefixed-name": "iso:point.name",
           "negated": "!<http://www.w3.org/1999/02/22-rdf-syntax-ns#type>", "variable": "?p"}


def _own_shape(tmp_path: Path, naming: str = "iri") -> Path:
    """A rule of one's own on an attribute no shipped check reads: points must not be named 'ORIGIN'."""
    name = NAMINGS[naming]
    prefixes = ('sh:prefixes [ sh:declare [ sh:prefix "iso" ; sh:namespace "' + STEPNC + '"^^xsd:anyURI ] ] ;'
                if naming == "prefixed-name" else "")
    path = tmp_path / "own.ttl"
    path.write_text(f"""@prefix sh: <http://www.w3.org/ns/shacl#> . @prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
<urn:own:NoOrigin> a sh:NodeShape ; sh:targetClass <{STEPNC}cartesian_point> ;
  sh:sparql [ {prefixes} sh:message "named ORIGIN" ;
    sh:select \"\"\"SELECT $this WHERE {{ $this {name} "ORIGIN" }}\"\"\" ] .
""")
    return path


@pytest.mark.parametrize("naming", NAMINGS)
@pytest.mark.parametrize("iso_shapes", [True, False], ids=["with-iso-shapes", "own-shapes-only"])
def test_a_check_of_ones_own_reads_the_attributes_it_names(tmp_path: Path, naming: str, iso_shapes: bool) -> None:
    """What the load leaves out is decided by the checks that run, one's own included: an
    attribute only an own check reads (by its IRI, by a prefixed name, or through a negated or
    variable predicate, which may read any) is in the graph."""
    report = validate([SHAFT], lenient=True, extra_shapes=[_own_shape(tmp_path, naming)], iso_shapes=iso_shapes)
    assert [(r.p21_id, r.message) for r in report.results if "ORIGIN" in r.message] == [(201, "named ORIGIN")]


@pytest.mark.parametrize("where", ["$this ?p 'ORIGIN'", "$this ?p ?v . FILTER(?v = 'ORIGIN')",
                                   "FILTER(true) $this ?p 'ORIGIN'", "$this ?p 'ORIGIN' ; a ?t"])
def test_a_variable_predicate_before_any_object_keeps_every_attribute(tmp_path: Path, where: str) -> None:
    """A check with a variable predicate may read any attribute, whatever its object is written as
    (a single-quoted literal was missed once, and every name left out)."""
    path = tmp_path / "own.ttl"
    path.write_text(f"""@prefix sh: <http://www.w3.org/ns/shacl#> .
<urn:own:NoOrigin> a sh:NodeShape ; sh:targetClass <{STEPNC}cartesian_point> ;
  sh:sparql [ sh:message "named ORIGIN" ; sh:select \"\"\"SELECT $this WHERE {{ {where} }}\"\"\" ] .
""")
    report = validate([SHAFT], lenient=True, extra_shapes=[path], iso_shapes=False)
    assert [(r.p21_id, r.message) for r in report.results if "ORIGIN" in r.message] == [(201, "named ORIGIN")]


def test_a_reference_to_an_unreadable_instance_is_found_in_an_attribute_no_check_reads(tmp_path: Path) -> None:
    """The dangling-reference check reads every attribute: with an unreadable instance, the load
    writes them all, and a reference from one no check reads is still reported."""
    program = _shaft(tmp_path, "#201=CARTESIAN_POINT('ORIGIN',(0.,0.,0.));",
                     "#201=CARTESIAN_POINT('ORIGIN',(0.,0.,0.));\n#202=MATERIAL('A' 'B',('C'));")
    program.write_text(program.read_text().replace("#11=MATERIAL('EN 10083-2','C45',(#12));",
                                                   "#11=MATERIAL('EN 10083-2','C45',(#12,#202));"))
    own = _own_shape(tmp_path)
    report = validate([program], lenient=True, extra_shapes=[own], iso_shapes=False)
    unresolved = [(r.p21_id, r.component) for r in report.results if "#202" in r.message]
    assert unresolved == [(11, "loader:P21-UNRESOLVED-REF")]


# -- the cheaper query forms --------------------------------------------------------------------------


def test_class_tests_name_only_the_classes_the_data_graph_holds() -> None:
    """A node can only be typed with a class some node has: the VALUES of a class test is the
    closure cut to the classes present (what the store joins each value node with), and ``false``
    when none is."""
    from stepnc_graph.validation.runner import Hierarchy, RunContext

    sub = {"<urn:C>": {"<urn:A>", "<urn:B>"}}
    ctx = RunContext(Hierarchy(sub, {}, []), {"<urn:A>", "<urn:X>"}, False)
    test = ctx.class_test("?v", "<urn:C>", 0)
    assert "<urn:A>" in test and "<urn:B>" not in test and "<urn:C>" not in test
    assert RunContext(Hierarchy(sub, {}, []), {"<urn:X>"}, False).class_test("?v", "<urn:C>", 0) == "false"
    typed = RunContext(Hierarchy(sub, {"<urn:C>": {"<urn:i>"}}, []), set(), False).class_test("?v", "<urn:C>", 0)
    assert typed == "(false || ?v IN (<urn:i>))"  # an individual the support files type still counts


@pytest.mark.parametrize("types", ["<urn:A>", "<urn:B>", "<urn:A> , <urn:B>", "<urn:Z>", "\"A\"", "[]", "<urn:Z> , <urn:B>"])
def test_a_class_test_answers_what_the_join_with_the_classes_answered(types: str) -> None:
    """The class test compares each of a node's types with the classes of the closure present
    (``FILTER IN``): what joining the node's types with them (``VALUES``) answered, whatever the
    node's types are (none in the closure, several, a literal or a blank node)."""
    from stepnc_graph.validation.runner import Hierarchy, RunContext

    store = ox.Store()
    g = ox.NamedNode("urn:graph")
    store.load(f"<urn:n> a {types} . <urn:m> a <urn:A> .".encode(), ox.RdfFormat.TURTLE, to_graph=g)
    ctx = RunContext(Hierarchy({"<urn:C>": {"<urn:A>", "<urn:B>"}}, {}, []), {"<urn:A>", "<urn:B>", "<urn:Z>"}, False)
    test = ctx.class_test("<urn:n>", "<urn:C>", 0)
    joined = "EXISTS { <urn:n> a ?c . VALUES ?c { <urn:A> <urn:B> } }"
    answers = [bool(store.query(f"ASK {{ FILTER({t}) }}", default_graph=g)) for t in (test, joined)]
    assert answers[0] == answers[1] == any(c in types for c in ("<urn:A>", "<urn:B>"))


@pytest.mark.parametrize("extra, expected", [
    ("", False),
    ("<urn:n> a <urn:A> , <urn:B> .", True),
    ("<urn:g> a <https://w3id.org/stepnc-graph/p21#ExchangeStructure> , <urn:Entity> , <urn:Other> .", False),
    ("<urn:g> a <https://w3id.org/stepnc-graph/p21#ExchangeStructure> , <urn:Entity> . <urn:n> a <urn:A> , <urn:B> .",
     True),
])
def test_multi_typed_counts_answer_what_the_self_join_answered(extra: str, expected: bool) -> None:
    from stepnc_graph.validation.runner import _multi_typed

    store = ox.Store()
    g = ox.NamedNode("urn:graph")
    store.load(f"<urn:a> a <urn:A> . <urn:b> a <urn:B> . {extra}".encode(), ox.RdfFormat.TURTLE, to_graph=g)
    ask = store.query("ASK { ?s a ?t1 , ?t2 FILTER(!sameTerm(?t1, ?t2)) FILTER NOT EXISTS "
                      "{ ?s a <https://w3id.org/stepnc-graph/p21#ExchangeStructure> } }", default_graph=g)
    assert _multi_typed(store, g) is bool(ask) is expected


def test_the_multi_typed_test_runs_beside_the_calling_thread(monkeypatch: pytest.MonkeyPatch) -> None:
    """The two counts of the multi-typed test (0.05-0.1 s at 100k instances) run on the checks'
    pool, beside the query of the classes present and the expanding of the checks on the calling
    thread: the report is the same, and the calling thread never runs them."""
    import threading

    from stepnc_graph.validation import runner

    before = validate([SHAFT], lenient=True)
    real = runner._multi_typed
    threads: list[threading.Thread] = []

    def where(store: ox.Store, g: ox.NamedNode) -> bool:
        threads.append(threading.current_thread())
        return real(store, g)

    monkeypatch.setattr(runner, "_multi_typed", where)
    after = validate([SHAFT], lenient=True)
    assert threads and threading.main_thread() not in threads
    assert [r.asdict() for r in after.results] == [r.asdict() for r in before.results]


# -- the scans of the text before the parse -------------------------------------------------------

#: the patterns the scans replace, as the reference (a leading ``\b`` or ``(?:^|...)`` made them slow)
OLD_DATA_OPENER = re.compile(r"\bDATA[ \t\r\n]*[(;]")

TEXTS = ["DATA;", "DATA ;\nDATA(('a'),('b'));", "ENDSEC;DATA;#1=X();ENDSEC;\nDATA ();", "XDATA;", "_DATA;",
         "a DATA\t(", "éDATA;", "'DATA;' DATA;", "DATADATA;", "DATA", "", "ΣDATA; DATA;"]


@pytest.mark.parametrize("text", TEXTS)
def test_data_openers_are_counted_as_the_word_bounded_pattern_counted(text: str) -> None:
    from stepnc_graph.loading.loader import _data_openers

    assert _data_openers(text) == len(OLD_DATA_OPENER.findall(text))


def _old_distinctive(text: str) -> list[str]:
    from stepnc_graph.mapping.editions import _distinctive

    only, _ = _distinctive()
    alternation = "|".join(sorted(only, key=len, reverse=True))
    old = re.compile(rf"(?:^|[;\s)])#\d+\s*=\s*({alternation})\s*\(", re.IGNORECASE | re.MULTILINE)
    return [m.group(1).upper() for m in old.finditer(text)]


@pytest.mark.parametrize("text", [
    "#1=MILLING_TOOL_BODY(1);", "#1 = milling_tool_body (2);\n#2=Milling_Tool_Body(3);",
    "x#3=MILLING_TOOL_BODY(3);", ")#4=MILLING_TOOL_BODY(3);", "'é'#5=MILLING_TOOL_BODY(1);\n#6=MILLING_TOOL_BODY(1);",
    "#7=CARTESIAN_POINT('',(0.,0.,0.));", "\t#8=\nMILLING_TOOL_BODY\n(", "ﬁ;#9=milling_tool_body(", ""])
def test_distinctive_names_are_found_as_the_old_pattern_found_them(text: str) -> None:
    from stepnc_graph.mapping.editions import _distinctive_names

    assert list(_distinctive_names(text)) == _old_distinctive(text)


def test_distinctive_names_of_the_fixtures_are_the_old_patterns() -> None:
    from stepnc_graph.mapping.editions import _distinctive_names

    programs = [*FIXTURES, *sorted((FIX / "editions").glob("*.stp"))]
    found = 0
    for program in programs:
        text = program.read_text(encoding="utf-8", errors="replace")
        names = list(_distinctive_names(text))
        assert names == _old_distinctive(text), program.name
        found += len(names)
    assert found > 0  # some fixture is of the 2001 edition


def test_the_tie_prefilter_agrees_with_the_exact_test() -> None:
    """``_tie_away_from_zero`` leaves the exact (Fraction) test to floats whose denominator divides
    ``2 * 10**places``: on every other float it could not find a tie; ties and near-ties agree."""
    from fractions import Fraction

    from stepnc_graph.mapping import ntriples as T

    def exact(value: float, text: str) -> str:
        places = len(text) - text.index(".") - 1
        num, den = value.as_integer_ratio()
        if abs(Fraction(num, den)) - abs(Fraction(text)) != Fraction(1, 2 * 10 ** places):
            return text
        return text[:-1] + str(int(text[-1]) + 1)

    values = [k / 2 ** j for k in range(-300, 300) for j in range(1, 12)]
    values += [562949953421312.25 + i for i in range(-50, 50)] + [0.1 * k for k in range(1000)]
    shown = [(v, repr(v)) for v in values if "." in repr(v) and "e" not in repr(v) and not repr(v).endswith(".0")]
    assert sum(T._tie_away_from_zero(v, t) != t for v, t in shown) > 10  # ties are among them
    assert [T._tie_away_from_zero(v, t) for v, t in shown] == [exact(v, t) for v, t in shown]
