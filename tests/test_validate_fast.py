"""`validate FILE`'s fast path: what it leaves out of the load and of the checks changes nothing in the
report, and the cheaper forms it uses (class tests, the multi-typed test, the text scans before
the parse) answer exactly what the forms they replace answered."""

from __future__ import annotations

import re
from pathlib import Path
import pyoxigraph as ox
import pytest

from stepnc_graph import api
from stepnc_graph.validation import _validate_store, compile_shapes, shape_files, validate

ROOT = Path(__file__).resolve().parent.parent
FIX = Path(__file__).parent / "fixtures"
FIXTURES = [ROOT / "examples" / "shaft_two_setups.stp", ROOT / "examples" / "shaft_damaged.stp",
            *sorted((FIX / "p21").glob("*.stp")), *sorted((FIX / "validate").glob("*.stp"))]


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
