"""Hostile and damaged input: every case answered cleanly, nothing of the file lost silently.

Each test here failed before the hardening of issue 7 (truncated files looped forever, one
Latin-1 byte re-decoded the whole file, syntax-broken instances vanished, exports of lenient
loads did not parse, only the first unresolved reference was reported, ...).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import stepnc_graph as sg
from stepnc_graph.core.naming import P21_NS
from stepnc_graph.part21 import Part21SyntaxError, read_file, read_text

from conftest import ROOT
from test_load import HEADER, assert_invariant, assert_round_trip, program, unreadable_ids

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"


def codes(r: sg.LoadResult) -> list[str]:
    return [d.code for d in r.diagnostics]


def rows(store: sg.api.GraphStore, graph: str, variables: str, pattern: str) -> list[tuple[str, ...]]:
    return sorted(tuple(t.value for t in row) for row in store.query(
        f"PREFIX p21: <{P21_NS}> SELECT {variables} WHERE {{ GRAPH <{graph}> {{ {pattern} }} }}"))


# -- truncated files (P1.2) ----------------------------------------------------------------------


def _cut_points(text: str) -> dict[str, int]:
    """One offset of each kind inside the DATA section of ``text``, and one in the header."""
    data = text.index("DATA;") + 5

    def inside(pattern: str) -> int:
        m = re.compile(pattern).search(text, data + (len(text) - data) // 3)
        assert m is not None, pattern
        return m.start() + 2

    return {
        "mid-string": inside(r"'[A-Z ]{4,}"),
        "mid-list": inside(r"\([#\d][^()]*,"),
        "mid-name": inside(r"=[A-Z_]{6,}\("),
        "mid-number": inside(r"\d\.\d"),
        "between-instances": text.index("\n#", data + (len(text) - data) // 3) + 1,
        "after-last-instance": text.index("ENDSEC;", data),
        "mid-endsec": text.index("ENDSEC;", data) + 3,
    }


@pytest.mark.parametrize("where", ["mid-string", "mid-list", "mid-name", "mid-number", "between-instances",
                                   "after-last-instance", "mid-endsec"])
def test_truncated_file_loads_what_precedes_the_cut(where: str, tmp_path: Path, time_bound: None) -> None:
    text = EXAMPLE.read_text()
    cut = _cut_points(text)[where]
    path = tmp_path / "cut.stp"
    path.write_text(text[:cut])
    store = sg.open_store(memory=True)
    with pytest.raises(Part21SyntaxError):
        sg.load(store, [path])
    [r] = sg.load(store, [path], lenient=True)
    # one diagnostic for the cut; the others are references to instances cut off
    assert codes(r).count("P21-TRUNCATED") == 1, r.diagnostics
    assert set(codes(r)) <= {"P21-TRUNCATED", "P21-UNRESOLVED-REF"}, r.diagnostics
    complete = len(re.findall(r"(?m)^#\d+=.*;\s*$", text[:cut]))
    assert r.instances - r.unreadable == complete  # every instance before the cut is loaded
    assert_invariant(path, store, r)
    assert_round_trip(store, r.graph, tmp_path, exclude=unreadable_ids(r))


def test_truncated_header_is_a_positioned_error_in_both_modes(tmp_path: Path, time_bound: None) -> None:
    text = EXAMPLE.read_text()
    path = tmp_path / "cut.stp"
    path.write_text(text[: text.index("FILE_SCHEMA") + 8])
    for lenient in (False, True):
        with pytest.raises(Part21SyntaxError) as e:
            sg.load(sg.open_store(memory=True), [path], lenient=lenient)
        assert e.value.line >= 1 and "end of file" in e.value.message


def test_missing_end_marker_only_is_a_warning(tmp_path: Path) -> None:
    path = tmp_path / "noend.stp"
    path.write_text(HEADER + "#1=PROPERTY_PARAMETER('a');\nENDSEC;\n")
    with pytest.raises(Part21SyntaxError, match="END-ISO-10303-21"):
        sg.load(sg.open_store(memory=True), [path])
    [r] = sg.load(sg.open_store(memory=True), [path], lenient=True)
    assert [(d.code, d.severity) for d in r.diagnostics] == [("P21-END-MISSING", "warning")]
    assert r.instances == 1


def test_instance_after_endsec_is_read_into_the_section(tmp_path: Path) -> None:
    path = tmp_path / "stray.stp"
    path.write_text(HEADER + "#1=PROPERTY_PARAMETER('a');\nENDSEC;\n#2=PROPERTY_PARAMETER('b');\nENDSEC;\n"
                    "END-ISO-10303-21;\n")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], lenient=True)
    # the second ENDSEC; closes the section #2 was read into
    assert [(d.code, d.p21_id) for d in r.diagnostics] == [("P21-OUTSIDE-SECTION", 2)]
    assert r.instances == 2


@pytest.mark.parametrize("after", ["END-ISO-10303-21;", "DATA;#3=PROPERTY_PARAMETER('c');ENDSEC;END-ISO-10303-21;"])
def test_a_section_without_endsec_is_closed_by_what_follows(after: str, tmp_path: Path) -> None:
    path = tmp_path / "noendsec.stp"
    path.write_text(HEADER + "#1=PROPERTY_PARAMETER('a');#2=PROPERTY_PARAMETER('b');" + after)
    with pytest.raises(Part21SyntaxError, match="ENDSEC"):
        sg.load(sg.open_store(memory=True), [path])
    [r] = sg.load(sg.open_store(memory=True), [path], lenient=True)
    assert [(d.code, d.severity, d.line, d.column) for d in r.diagnostics] == [("P21-ENDSEC-MISSING", "warning", 2, 55)]
    assert r.instances == 2 + after.count("#3=")


# -- encoding (P2.4) ------------------------------------------------------------------------------


def test_a_latin1_byte_is_reported_and_utf8_elsewhere_is_kept(tmp_path: Path) -> None:
    data = HEADER + "#1=PROPERTY_PARAMETER('D\u00d880 UTF-8');\n#2=PROPERTY_PARAMETER('D"
    raw = data.encode("utf-8") + b"\xd880 LATIN-1');\nENDSEC;END-ISO-10303-21;\n"
    path = tmp_path / "mixed.stp"
    path.write_bytes(raw)
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path])
    [d] = r.diagnostics
    assert (d.code, d.severity, d.line, d.column) == ("P21-ENCODING", "warning", 3, 25)
    assert "0xD8" in d.message
    names = rows(store, r.graph, "?s ?n", "?s <https://w3id.org/stepnc-graph/iso14649#property_parameter.parameter_name> ?n")
    assert sorted(n for _, n in names) == ["D\u00d880 LATIN-1", "D\u00d880 UTF-8"]
    assert "\u00c3" not in sg.export(store, "ttl", r.graph).decode("utf-8")  # no mojibake anywhere


def test_many_undecodable_bytes_are_summarised(tmp_path: Path) -> None:
    body = "".join(f"#{i}=PROPERTY_PARAMETER('X\xe9');\n" for i in range(1, 301))
    path = tmp_path / "latin1.stp"
    path.write_bytes((HEADER + body + "ENDSEC;END-ISO-10303-21;\n").encode("latin-1"))
    [r] = sg.load(sg.open_store(memory=True), [path])
    assert len(r.diagnostics) == 101 and "200 more" in r.diagnostics[-1].message
    assert r.instances == 300 and r.raw == 0


def test_a_bom_is_not_content(tmp_path: Path) -> None:
    path = tmp_path / "bom.stp"
    path.write_bytes(b"\xef\xbb\xbf" + (HEADER + "#1=PROPERTY_PARAMETER('a');\nENDSEC;END-ISO-10303-21;\n").encode())
    [r] = sg.load(sg.open_store(memory=True), [path])
    assert r.diagnostics == [] and r.instances == 1


# -- unreadable instances are kept (P2.7), repaired ones export strictly (P2.6) ----------------------


def test_an_unreadable_instance_keeps_its_text_and_exports_as_a_comment(tmp_path: Path) -> None:
    data = "#1=CONST_SPINDLE_SPEED(5.,,);\n#2=TURNING_TECHNOLOGY($,.TCP.,#1,.F.,.F.,.F.);"
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, data)], lenient=True)
    assert [(d.code, d.p21_id) for d in r.diagnostics] == [("P21-SYNTAX", 1), ("P21-UNRESOLVED-REF", 2)]
    assert (r.instances, r.raw, r.unreadable) == (2, 1, 1)
    [(node, text, name, why)] = rows(store, r.graph, "?s ?t ?n ?e", "?s a p21:UnreadableInstance ; p21:rawText ?t ; "
                                                     "p21:entityName ?n ; p21:syntaxError ?e")
    assert node.endswith("/i1") and text == "#1=CONST_SPINDLE_SPEED(5.,,);" and name == "CONST_SPINDLE_SPEED"
    assert "expected a parameter value" in why
    exported = sg.export(store, "p21", r.graph).decode()
    assert "/* stepnc-graph: #1 could not be read" in exported and "#1=CONST_SPINDLE_SPEED(5.,,);" in exported
    again = tmp_path / "again.stp"
    again.write_text(exported)
    [r2] = sg.load(sg.open_store(memory=True), [again])  # strict: the export always parses
    assert [(d.code, d.p21_id) for d in r2.diagnostics] == [("P21-UNRESOLVED-REF", 2)]


def test_a_comment_end_inside_unreadable_text_cannot_end_the_comment(tmp_path: Path) -> None:
    data = "#1=CONST_SPINDLE_SPEED(5.,/* x */,);"
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, data)], lenient=True)
    exported = sg.export(store, "p21", r.graph).decode()
    again = tmp_path / "again.stp"
    again.write_text(exported)
    [r2] = sg.load(sg.open_store(memory=True), [again])
    assert r2.instances == 0 and r2.diagnostics == []


@pytest.mark.parametrize("damage,code", [
    ("#1=NOT_IN_SCHEMA('a\u2019);\n#2=PROPERTY_PARAMETER('b');", "P21-CURLY-QUOTE"),
    ("#1=NOT_IN_SCHEMA('a')\n#2=PROPERTY_PARAMETER('b');", "P21-MISSING-SEMICOLON"),
    ("#1=NOT_IN_SCHEMA(TCP);\n#2=PROPERTY_PARAMETER('b');", "P21-BARE-ENUM"),
])
def test_a_repaired_raw_instance_exports_its_repaired_text(damage: str, code: str, tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    path = program(tmp_path, damage)
    [r] = sg.load(store, [path], lenient=True)
    assert code in codes(r) and "P21-UNKNOWN-ENTITY" in codes(r)
    [(raw, repaired)] = rows(store, r.graph, "?raw ?fixed", "?s p21:rawText ?raw ; p21:repairedText ?fixed")
    assert raw == path.read_text()[path.read_text().index("#1="):].split("\n")[0].rstrip()  # the evidence
    again = tmp_path / "again.stp"
    again.write_bytes(sg.export(store, "p21", r.graph))
    [r2] = sg.load(sg.open_store(memory=True), [again])  # strict
    assert codes(r2) == ["P21-UNKNOWN-ENTITY"] and repaired in again.read_text()
    assert_round_trip(store, r.graph, tmp_path)


def test_seed_annex_programs_export_strictly(tmp_path: Path) -> None:
    for path in sorted((ROOT / "tests" / "fixtures" / "p21").glob("fail_*.stp")):
        store = sg.open_store(memory=True)
        [r] = sg.load(store, [path], lenient=True)
        again = tmp_path / path.name
        again.write_bytes(sg.export(store, "p21", r.graph))
        sg.load(sg.open_store(memory=True), [again])  # raises if the export does not parse strictly


def test_a_later_definition_keeps_its_text(tmp_path: Path) -> None:
    data = "#1=PROPERTY_PARAMETER('a');\n#2=PROPERTY_PARAMETER('b');\n#1=PROPERTY_PARAMETER('again');"
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, data)], lenient=True)
    assert [(d.code, d.p21_id) for d in r.diagnostics] == [("P21-DUPLICATE-ID", 1)]
    [(node, text, line)] = rows(store, r.graph, "?s ?t ?l", "?s p21:duplicateDefinition [ p21:rawText ?t ; "
                                                             "p21:line ?l ]")
    assert node.endswith("/i1") and text == "#1=PROPERTY_PARAMETER('again');" and line == "4"
    assert "later definition of #1 (line 4), not loaded: #1=PROPERTY_PARAMETER('again');" in sg.export(
        store, "p21", r.graph).decode()


def test_identical_later_definitions_are_all_kept(tmp_path: Path) -> None:
    again = "#1=PROPERTY_PARAMETER('again');"
    data = f"#1=PROPERTY_PARAMETER('a');\n{again}\n{again}\n{again}"
    store = sg.open_store(memory=True)
    path = program(tmp_path, data)
    [r] = sg.load(store, [path], lenient=True)
    assert_invariant(path, store, r)
    assert sg.export(store, "p21", r.graph).decode().count("later definition of #1") == 3


# -- every unresolved reference (P3.10) --------------------------------------------------------------


def test_every_unresolved_reference_is_reported(tmp_path: Path) -> None:
    data = ("#2=NOT_AN_ENTITY(#999,#1);\n#5=AXIS2_PLACEMENT_3D('x',#97,#98,#99);\n"
            "#6=MATERIAL('s','m',(#7,#8));\n#7=PROPERTY_PARAMETER('x');")
    [r] = sg.load(sg.open_store(memory=True), [program(tmp_path, data)])
    refs = sorted((d.p21_id, re.search(r"#(\d+)", d.message).group(1))  # type: ignore[union-attr]
                  for d in r.diagnostics if d.code == "P21-UNRESOLVED-REF")
    assert refs == [(2, "1"), (2, "999"), (5, "97"), (5, "98"), (5, "99"), (6, "8")]
    assert codes(r).count("P21-UNKNOWN-ENTITY") == 1


# -- SET order (P3.12) -------------------------------------------------------------------------------


def test_set_members_are_written_in_ascending_id_order(tmp_path: Path) -> None:
    data = "#1=MATERIAL('s','m',(#67,#113,#9));\n#9=PROPERTY_PARAMETER('a');\n" \
           "#67=PROPERTY_PARAMETER('b');\n#113=PROPERTY_PARAMETER('c');"
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, data)])
    assert "#1=MATERIAL('s','m',(#9,#67,#113));" in sg.export(store, "p21", r.graph).decode()


# -- error output (P3.8) ---------------------------------------------------------------------------


def test_errors_show_a_window_of_a_huge_line_with_control_characters_escaped(tmp_path: Path) -> None:
    line = "#1=PROPERTY_PARAMETER('" + "x" * 5_000_000 + "'),\x1b[31mRED;"
    text = HEADER.replace("\n", "") + line + "ENDSEC;END-ISO-10303-21;"
    with pytest.raises(Part21SyntaxError) as e:
        list(read_text(text, "huge.stp").instances())
    shown = str(e.value)
    assert len(shown) < 600 and "\x1b" not in shown and "\\x1b" in shown
    assert len(str(e.value.asdict())) < 800
    lines = shown.splitlines()
    assert lines[-1].index("^") == lines[-2].index("),") + 1  # the caret under the offending ','


def test_messages_cut_huge_tokens(tmp_path: Path) -> None:
    text = HEADER + "#1=PROPERTY_PARAMETER('a') '" + "y" * 1_000_000 + "';\nENDSEC;END-ISO-10303-21;"
    with pytest.raises(Part21SyntaxError) as e:
        list(read_text(text, "t.stp").instances())
    assert len(e.value.message) < 200 and "1000002 characters" in e.value.message


# -- not Part 21 at all ------------------------------------------------------------------------------


@pytest.mark.parametrize("source", ["/dev/zero", "/dev/urandom"])
def test_devices_are_refused_at_once(source: str, time_bound: None) -> None:
    if not Path(source).exists():
        pytest.skip(f"{source} is not on this system")
    with pytest.raises(OSError, match="not a regular file"):
        sg.load(sg.open_store(memory=True), [source])


def test_binary_input_is_not_part21(tmp_path: Path) -> None:
    path = tmp_path / "blob.stp"
    path.write_bytes(bytes(range(256)) * 1000)
    for lenient in (False, True):
        with pytest.raises(Part21SyntaxError, match="not a Part 21 file") as e:
            read_file(path, lenient)
        assert "\x00" not in str(e.value)


def test_a_repaired_header_exports_strictly(tmp_path: Path) -> None:
    path = tmp_path / "header.stp"
    path.write_text(HEADER.replace("'2;1'", "T") + "#1=PROPERTY_PARAMETER('a');\nENDSEC;END-ISO-10303-21;\n")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], lenient=True)
    assert "P21-BARE-ENUM" in codes(r)
    [(original,)] = rows(store, r.graph, "?t", "?g p21:headerText ?t")
    assert "'2;1'" not in original and ",T)" in original  # the evidence stays
    again = tmp_path / "again.stp"
    again.write_bytes(sg.export(store, "p21", r.graph))
    [r2] = sg.load(sg.open_store(memory=True), [again])  # strict
    assert r2.instances == 1 and "FILE_DESCRIPTION((''),.T.);" in again.read_text()


# -- fuzzing: a sample of bench/fuzz_load.py's run --------------------------------------------------


@pytest.mark.parametrize("chunk", range(4))
def test_damaged_programs_keep_every_promise(chunk: int, time_bound: None) -> None:
    """No exception but the documented ones, the invariant, a strictly parseable export."""
    import random

    from stepnc_graph.testing.fuzz import check, mutate

    programs = [EXAMPLE.read_bytes(), *(p.read_bytes() for p in sorted((ROOT / "tests" / "fixtures" / "p21").glob(
        "*.stp")))]
    for index in range(chunk * 15, chunk * 15 + 15):
        rng = random.Random(index)
        kind, data = mutate(rng, rng.choice(programs), programs)
        outcome = check(data)
        assert outcome.status in ("ok", "rejected"), (index, kind, outcome.detail)


@pytest.mark.parametrize("kind", ["one-line", "multi-instance", "huge-number"])
def test_relaid_programs_and_huge_numbers_keep_every_promise(kind: str, time_bound: None) -> None:
    """The damages of issue 26: programs on one line or several instances a line, then an instance
    broken; integers, reals, #ids and references made huge (a sample of the fuzz run's)."""
    import random

    from stepnc_graph.testing.fuzz import check, mutate

    programs = [EXAMPLE.read_bytes(), *(p.read_bytes() for p in sorted((ROOT / "tests" / "fixtures" / "p21").glob(
        "*.stp")))]
    for index in range(8):
        rng = random.Random(index)
        _, data = mutate(rng, rng.choice(programs), programs, [kind])
        outcome = check(data)
        assert outcome.status in ("ok", "rejected"), (index, kind, outcome.detail)


def test_the_fuzz_check_finds_text_neither_loaded_nor_kept() -> None:
    """The check measures what is kept by itself: a reader that dropped a span is caught."""
    from types import SimpleNamespace

    from stepnc_graph.testing.fuzz import _unkept_text

    text = HEADER + "#1=A(1);\n/* c */ #2=B(2); ENDSEC;END-ISO-10303-21;\n"
    reader = read_text(text, "t.stp", lenient=True)
    instances = list(reader.instances())
    assert _unkept_text(reader, instances) == ""
    dropped = SimpleNamespace(text=text, body_start=reader.body_start, duplicate_texts=[], unreadable_texts=[])
    assert "#2=B(2);" in _unkept_text(dropped, instances[:1])


def test_the_fuzz_check_finds_an_outbound_connection(monkeypatch: pytest.MonkeyPatch) -> None:
    """A load that connects anywhere fails the JSON-LD check: to the loopback listener (which
    counts), or anywhere else (the audit hook sees the socket)."""
    import socket
    import urllib.request

    from stepnc_graph.testing import fuzz

    listener = fuzz.LoopbackListener()
    fuzz.watch_network()

    def fetching(store: object, paths: list[Path], **_: object) -> None:
        urllib.request.urlopen(listener.url, timeout=5).close()  # noqa: S310 -- the test's own listener

    def connecting(store: object, paths: list[Path], **_: object) -> None:
        with socket.create_connection(("127.0.0.1", listener.port), timeout=5):
            pass

    try:
        for load in (fetching, connecting):
            monkeypatch.setattr(sg, "load", load)
            outcome = fuzz.check_jsonld(b"{}", listener)
            assert outcome.status == "failed" and outcome.detail.startswith("network"), outcome
    finally:
        listener.close()
    assert listener.connections == 2


def test_a_repaired_instance_or_header_with_a_real_beyond_a_double_exports_strictly(tmp_path: Path) -> None:
    """The repaired text is written from the parsed values, where such a real is infinity: it is
    written as a real beyond a double again (found by the fuzz run: the export did not parse; a
    repaired HEADER with one crashed the load)."""
    path = tmp_path / "inf.stp"
    path.write_text(HEADER.replace("'2;1'", "T,-1.E999") + "#1=NOT_IN_SCHEMA(1.E999,CW);\n"
                    "#2=PROPERTY_PARAMETER('a');\nENDSEC;END-ISO-10303-21;\n")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], lenient=True)
    assert codes(r).count("P21-BARE-ENUM") == 2 and "P21-UNKNOWN-ENTITY" in codes(r)
    [(fixed,)] = rows(store, r.graph, "?t", "?s p21:repairedText ?t")
    assert fixed == "#1=NOT_IN_SCHEMA(1.E999,.CW.);"
    again = tmp_path / "again.stp"
    again.write_bytes(sg.export(store, "p21", r.graph))
    [r2] = sg.load(sg.open_store(memory=True), [again])  # strict
    assert r2.instances == 2 and "FILE_DESCRIPTION((''),.T.,-1.E999);" in again.read_text()


def test_jsonld_damages_of_every_kind_are_made() -> None:
    """The JSON-LD damages never fail themselves (a 1,000-deep context once hit json.dumps's
    recursion limit and ended a fuzz run); every kind is made, and the URL lands in a context."""
    import random
    from collections import Counter

    from stepnc_graph.testing.fuzz import JSONLD_KINDS, mutate_jsonld

    store = sg.open_store(memory=True)
    [r] = sg.load(store, [ROOT / "tests" / "fixtures" / "p21" / "pass_edition3.stp"])
    doc = sg.export(store, "jsonld", r.graph)
    made: Counter[str] = Counter()
    for index in range(240):
        kind, data = mutate_jsonld(random.Random(index), doc, "http://127.0.0.1:9/c.jsonld")
        made[kind] += 1
        assert isinstance(data, bytes) and data
        if kind == "jsonld-context":
            assert b"http://127.0.0.1:9/c.jsonld" in data
    assert set(made) == set(JSONLD_KINDS)


@pytest.mark.parametrize("number", ["1.E999", "-1.E999", "1" * 400])
def test_a_real_no_double_can_hold_is_kept_raw(number: str, tmp_path: Path) -> None:
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, f"#1=CONST_SPINDLE_SPEED({number});")])
    [d] = r.diagnostics
    assert (d.code, d.p21_id) == ("P21-VALUE-TYPE", 1) and "out of the range of a double" in d.message
    assert f"#1=CONST_SPINDLE_SPEED({number});" in sg.export(store, "p21", r.graph).decode()


# -- recovery at instance boundaries: one-line files, several instances a line (issue 26) ----------


def _one_line(text: str) -> str:
    """``text`` with its line ends replaced by spaces: a program written on one line."""
    return re.sub(r"\r?\n", " ", text)


def test_a_one_line_program_loses_nothing_after_a_syntax_error(tmp_path: Path) -> None:
    text = _one_line(EXAMPLE.read_text()).replace("#20=SETUP('SETUP 1'", "#20=SETUP('SETUP \\Q1'")
    path = tmp_path / "one.stp"
    path.write_text(text)
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], lenient=True)
    assert (r.instances, r.unreadable) == (89, 1)
    assert [(d.code, d.p21_id) for d in r.diagnostics] == [("P21-UNRESOLVED-REF", 3), ("P21-SYNTAX", 20)]
    [(node, raw)] = rows(store, r.graph, "?s ?t", "?s a p21:UnreadableInstance ; p21:rawText ?t")
    assert node.endswith("/i20") and raw == "#20=SETUP('SETUP \\Q1',#200,#22,(#21));"
    assert len(instance_ids(store, r.graph)) == len(re.findall(r"#\d+=", EXAMPLE.read_text())) == 89
    assert_round_trip(store, r.graph, tmp_path, exclude=unreadable_ids(r))


def instance_ids(store: sg.api.GraphStore, graph: str) -> set[int]:
    return {int(i) for (i,) in rows(store, graph, "?i", "?s p21:id ?i")}


def test_text_naming_no_instance_is_kept_in_the_graph_and_exported(tmp_path: Path) -> None:
    data = "#1=PROPERTY_PARAMETER('a');#=PROPERTY_PARAMETER('lost id');#2=PROPERTY_PARAMETER('b');"
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, data)], lenient=True)
    assert [(d.code, d.p21_id, d.line, d.column) for d in r.diagnostics] == [("P21-SYNTAX", None, 2, 28)]
    assert instance_ids(store, r.graph) == {1, 2} and (r.instances, r.unreadable_texts) == (2, 1)
    [(text, line, why)] = rows(store, r.graph, "?t ?l ?e", "?g p21:unreadableText [ p21:rawText ?t ; p21:line ?l ; "
                                                           "p21:syntaxError ?e ]")
    assert (text, line) == ("#=PROPERTY_PARAMETER('lost id');", "2") and "'#'" in why
    exported = sg.export(store, "p21", r.graph).decode()
    assert "#=PROPERTY_PARAMETER('lost id');" in exported
    again = tmp_path / "again.stp"
    again.write_text(exported)
    [r2] = sg.load(sg.open_store(memory=True), [again])  # strict: the text is a comment
    assert r2.instances == 2 and r2.diagnostics == []


def test_a_reference_to_an_instance_inside_unreadable_text_is_reported(tmp_path: Path) -> None:
    # '#2=' occurs, but inside the string of an unreadable instance: no instance #2 is loaded
    data = "#1=PROPERTY_PARAMETER('x;#2=PROPERTY_PARAMETER(', 'a\\Q');\n#3=MATERIAL('s','m',(#2));"
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [program(tmp_path, data)], lenient=True)
    assert instance_ids(store, r.graph) == {1, 3}
    assert [(d.code, d.p21_id) for d in r.diagnostics] == [("P21-SYNTAX", 1), ("P21-UNRESOLVED-REF", 3)]
    assert "#2" in r.diagnostics[1].message


HUGE = "7" * 5000


@pytest.mark.parametrize("data,p21_id", [
    (f"#1=PROPERTY_PARAMETER({HUGE});", 1),
    (f"#1=MATERIAL('s','m',(#{HUGE}));", 1),
    (f"#{HUGE}=PROPERTY_PARAMETER('a');", None),
])
def test_a_huge_integer_is_a_positioned_error_never_a_traceback(data: str, p21_id: int | None, tmp_path: Path) -> None:
    import subprocess
    import sys

    path = program(tmp_path, data + "\n#5=PROPERTY_PARAMETER('after');")
    ident = f" #{p21_id}:" if p21_id is not None else ""
    cli = [sys.executable, "-m", "stepnc_graph.cli"]
    strict = subprocess.run([*cli, "load", "--memory", str(path)], capture_output=True, text=True, timeout=120)
    assert strict.returncode == 2 and "Traceback" not in strict.stderr, strict.stderr
    assert f"{path}:2:" in strict.stderr and ident in strict.stderr and "5000 digits" in strict.stderr
    lenient = subprocess.run([*cli, "load", "--memory", "--lenient", str(path)], capture_output=True, text=True,
                             timeout=120)
    assert lenient.returncode == 1 and "Traceback" not in lenient.stderr + lenient.stdout, lenient.stderr
    assert "P21-SYNTAX" in lenient.stdout + lenient.stderr
    validate = subprocess.run([*cli, "validate", str(path)], capture_output=True, text=True, timeout=120)
    assert validate.returncode == 1 and "Traceback" not in validate.stderr + validate.stdout, validate.stderr
    [result] = [line for line in validate.stdout.splitlines() if "5000 digits" in line]  # a positioned result
    assert result.split()[:2] == ["line", "2"] and (p21_id is None or f"#{p21_id}" in result)


def test_the_fuzz_check_reads_section_keywords_in_any_case() -> None:
    """Names are case-insensitive (docs/loading.md), so the reader reads ``eNDSEC;`` as ENDSEC; the
    check said that text was lost (the fuzz run's input 36678)."""
    from stepnc_graph.testing.fuzz import check

    text = EXAMPLE.read_text(encoding="utf-8")
    assert text.count("\nENDSEC;") >= 2
    damaged = text[::-1].replace("\n;CESDNE", "\n;CESDNe", 1)[::-1]  # the last ENDSEC, of DATA
    assert check(damaged.encode("utf-8")).status == "ok"


def test_a_data_opener_lenient_mode_repaired_exports_strict_part21_and_keeps_the_text(tmp_path: Path) -> None:
    """Before: the opener was kept verbatim (``(MACHINING_SCHEMA)``, a bare name lenient mode reads
    as an enumeration) and the export did not read strictly (the fuzz run's input 52991)."""
    import stepnc_graph as sg
    from stepnc_graph.testing.fuzz import check

    text = (ROOT / "tests" / "fixtures" / "p21" / "pass_edition3.stp").read_text(encoding="utf-8")
    bad = "DATA('geometry',(MACHINING_SCHEMA));"
    damaged = text.replace("DATA('geometry',('MACHINING_SCHEMA'));", bad)
    assert damaged != text
    path = tmp_path / "opener.stp"
    path.write_text(damaged, encoding="utf-8")
    store = sg.open_store(memory=True)
    [r] = sg.load(store, [path], lenient=True)
    assert any(d.code == "P21-BARE-ENUM" for d in r.diagnostics)
    exported = sg.export(store, "p21", r.graph).decode("utf-8")
    assert "DATA('geometry',(.MACHINING_SCHEMA.));" in exported
    assert f"this DATA section's opening as read: {bad}" in exported
    assert len(list(read_text(exported, "exported.stp").instances())) == 6
    assert check(damaged.encode("utf-8")).status == "ok"
