"""Part 21 reader: structure, values, strings, positions, errors, lenient recovery, fuzzing."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stepnc_graph.part21 import (
    DERIVED,
    UNSET,
    Binary,
    Enum,
    Name,
    Part21SyntaxError,
    Ref,
    Typed,
    read_file,
    read_text,
)
from stepnc_graph.part21.strings import StringDecodeError, decode, encode

from conftest import FIXTURES

P21 = FIXTURES / "p21"


def wrap(data: str, header: str | None = None) -> str:
    header = header or "FILE_DESCRIPTION(('t'),'2;1');FILE_NAME('t','',(''),(''),'','','');FILE_SCHEMA(('S'));"
    return f"ISO-10303-21;\nHEADER;\n{header}\nENDSEC;\nDATA;\n{data}\nENDSEC;\nEND-ISO-10303-21;\n"


def instances(data: str, lenient: bool = False):  # type: ignore[no-untyped-def]
    r = read_text(wrap(data), "t.stp", lenient)
    return list(r.instances()), r


def test_every_parameter_kind() -> None:
    [inst], _ = instances("#1=E(1,-2,+3,1.,-2.5E-3,1.5e+2,'it''s',.TCP.,.t.,\"0FF\",$,*,#22,(),(1,(2,3)),"
                          "LENGTH_MEASURE(2.5),/* a comment */ ENTITY_NAME_X((#1)));")
    assert inst.name == "E" and inst.id == 1
    assert inst.params == [1, -2, 3, 1.0, -2.5e-3, 150.0, "it's", Enum("TCP"), Enum("T"), Binary("0FF"), UNSET,
                           DERIVED, Ref(22), [], [1, [2, 3]], Typed("LENGTH_MEASURE", 2.5),
                           Typed("ENTITY_NAME_X", [Ref(1)])]
    assert isinstance(inst.params[0], int) and isinstance(inst.params[3], float)
    assert isinstance(inst.params[12], Ref)


#: parameter values of every kind, as tokens (a string holds no space: the test spaces tokens apart)
_VALUE_TOKENS = ["#12", "'it''s'", "'\\X2\\00E9\\X0\\'", "''", "1.5", "-2.", "3", "+4", "1.E-3", "-2.5e+2", ".T.",
                 ".tcp.", "$", "*", "\"0F\"", "#ORIGIN", "@12", "1" * 30]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.one_of(st.sampled_from(_VALUE_TOKENS).map(lambda v: [v]),  # a value
                          st.lists(st.sampled_from(_VALUE_TOKENS), max_size=3).map(  # a list of values
                              lambda v: ["(", *[t for i, m in enumerate(v) for t in ([","] if i else []) + [m]], ")"]),
                          st.sampled_from(_VALUE_TOKENS).map(lambda v: ["LENGTH_MEASURE", "(", v, ")"])),  # typed
                max_size=6))
def test_compact_and_spaced_parameters_read_alike(values: list[list[str]]) -> None:
    """The reader reads a value and the ',' or ')' after it in one step when nothing separates
    them (the common case), token by token otherwise: both give the same values."""
    tokens: list[str] = ["("]
    for k, v in enumerate(values):
        tokens += [","] * (k > 0) + v
    tokens.append(")")
    [compact], _ = instances(f"#1=E{''.join(tokens)};")
    [spaced], _ = instances(f"#1 = E {' '.join(tokens)} ;")
    assert compact.params == spaced.params
    assert [type(v) for v in compact.params] == [type(v) for v in spaced.params]


def test_complex_instance_and_case_insensitive_names() -> None:
    [inst], _ = instances("#5=(Point(1.)Cartesian_Point((0.,1.))representation_item(''));")
    assert inst.name is None
    assert inst.names == ["POINT", "CARTESIAN_POINT", "REPRESENTATION_ITEM"]
    assert inst.parts and inst.parts[1][1] == [[0.0, 1.0]]


def test_header_multiple_schemas_and_data_sections() -> None:
    text = ("ISO-10303-21;HEADER;FILE_DESCRIPTION(('d'),'2;1');FILE_NAME('n','t',('a'),('o'),'p','s','x');"
            "FILE_SCHEMA(('MACHINING_SCHEMA','milling_schema'));MY_HEADER_EXT(1);ENDSEC;"
            "DATA('one',('MACHINING_SCHEMA'));#1=A();ENDSEC;DATA('two',('MILLING_SCHEMA'));#2=B();ENDSEC;"
            "END-ISO-10303-21;")
    r = read_text(text)
    assert [i.id for i in r.instances()] == [1, 2]
    assert r.header.schemas == ["MACHINING_SCHEMA", "MILLING_SCHEMA"]
    assert r.header.entities["MY_HEADER_EXT"] == [1]
    assert r.header.data_sections == [["one", ["MACHINING_SCHEMA"]], ["two", ["MILLING_SCHEMA"]]]


def test_edition3_sections() -> None:
    r = read_file(P21 / "pass_edition3.stp")
    found = [(i.id, i.section) for i in r.instances()]
    h = r.header
    assert found == [(1, 0), (2, 0), (3, 0), (4, 0), (5, 1), (6, 1)]
    assert h.data_section_texts == ["DATA('process',('MACHINING_SCHEMA','TURNING_SCHEMA'));",
                                    "DATA('geometry',('MACHINING_SCHEMA'));"]
    assert h.anchors == [("face_step", 3), ("origin", 5)]  # <feed>=0.25 names a value, not an instance
    assert h.anchor_text.startswith("ANCHOR;") and h.anchor_text.endswith("ENDSEC;") and "{units:'mm'}" in h.anchor_text
    assert h.references == [("#900", "library.stp#spindle_800"), ("@901", "library.stp#stock")]
    assert h.reference_text.startswith("REFERENCE;") and "/* a spindle speed" in h.reference_text
    assert len(h.signatures) == 1 and h.signatures[0].startswith("SIGNATURE") and h.signatures[0].endswith(";")
    assert r.diagnostics == []


def test_edition3_names_as_values() -> None:
    [inst], _ = instances("#1=E(@12,#ORIGIN,@PI,(#2,@3));")
    assert inst.params == [Name("@12"), Name("#ORIGIN"), Name("@PI"), [Ref(2), Name("@3")]]
    assert all(type(v) is Name for v in inst.params[:3])


@pytest.mark.parametrize("section, line, column, expected", [
    ("ANCHOR;\n<a>=#1\nENDSEC;", 7, 1, "';'"),               # missing ';' after an anchor
    ("ANCHOR;\na=#1;\nENDSEC;", 6, 1, "anchor name"),         # a name without <>
    ("REFERENCE;\n#5=#6;\nENDSEC;", 6, 4, "<uri>"),           # not a resource
    ("REFERENCE;\n#A=<x.stp#a>;\nENDSEC;", 6, 1, "#id, @id"),  # a constant cannot be defined outside
    ("REFERENCE;\n@_B=<x.stp#b>;\nENDSEC;", 6, 1, "#id, @id"),  # nor one whose name starts with '_'
])
def test_edition3_section_errors_are_positioned(section: str, line: int, column: int, expected: str) -> None:
    text = wrap("#1=E();").replace("DATA;", section + "\nDATA;")
    for lenient in (False, True):  # section structure is not repaired: it would change what links resolve to
        with pytest.raises(Part21SyntaxError) as err:
            read_text(text, "t.stp", lenient)
        assert (err.value.lineno, err.value.offset) == (line, column) and expected in err.value.msg


def test_positions_survive_any_line_endings() -> None:
    for eol in ("\n", "\r\n", "\r\n\n"):
        text = wrap("#1=A();" + eol + "  #2=B(" + eol + "1);").replace("\n", eol) if eol != "\n" else \
            wrap("#1=A();\n  #2=B(\n1);")
        got = [(i.id, i.column) for i in read_text(text).instances()]
        assert got == [(1, 1), (2, 3)]
    [a, b] = read_text(wrap("#1=A();\n  #2=B(\n1);")).instances()
    assert (a.line, b.line) == (6, 7)


def test_very_long_line() -> None:
    data = "#1=A((" + ",".join(str(i) for i in range(200_000)) + "));"
    [inst], _ = instances(data)
    assert len(inst.params[0]) == 200_000 and inst.params[0][-1] == 199_999


@pytest.mark.parametrize("content,expected", [
    ("abc", "abc"), ("it''s", "it's"), ("a\\\\b", "a\\b"),
    ("\\S\\D", "\u00c4"), ("\\PA\\\\S\\D", "\u00c4"), ("\\PE\\\\S\\D", "\u0424"),  # ISO 8859-5 0xC4: Cyrillic EF
    ("\\X\\E9t\\X\\E9", "\u00e9t\u00e9"), ("\\X2\\00E9004D\\X0\\", "\u00e9M"),
    ("\\X4\\0001F600\\X0\\", "\U0001F600"), ("\\X2\\D83DDE00\\X0\\", "\U0001F600"),
    ("line\nbreak", "linebreak"), ("a\\N\\b\\F\\", "ab"),
])
def test_string_decoding(content: str, expected: str) -> None:
    assert decode(content) == expected


@pytest.mark.parametrize("content", ["a\\Q\\b", "\\S\\\u00e9", "\\S\\\U0001F600"])
def test_invalid_escape(content: str) -> None:
    """``\\S\\`` shifts a character of the basic alphabet; any other is an error, not a crash."""
    with pytest.raises(StringDecodeError):
        decode(content)


@settings(max_examples=300)
@given(st.text())
def test_string_encode_decode_round_trip(value: str) -> None:
    value = value.replace("\r", "").replace("\n", "")
    literal = encode(value)
    assert all(" " <= c <= "~" for c in literal)
    assert decode(literal[1:-1]) == value


# -- errors -------------------------------------------------------------------

ERRORS = [
    ("#1=A(1,2;", 6, 9, 1, "expected ',' or ')'"),
    ("#1=A(1)", 7, 1, 1, "expected ';'"),
    ("#1=A('open);", 6, 6, 1, "string is never closed"),
    ("#1 A();", 6, 4, 1, "expected '='"),
    ("#1=A(1)(;", 6, 8, 1, "expected ';'"),
    ("#1=A(.X);", 6, 6, 1, "found '.'"),
    ("#1=A(CW);", 6, 6, 1, "enumeration values are written .CW."),
    ("#1=A();\n#1=B();", 7, 1, 1, "defined again"),
    ("#1=A(X(1,2));", 6, 11, 1, "exactly one value"),
]


@pytest.mark.parametrize("data,line,column,p21_id,message", ERRORS)
def test_strict_errors_are_positioned(data: str, line: int, column: int, p21_id: int, message: str) -> None:
    with pytest.raises(Part21SyntaxError) as info:
        list(read_text(wrap(data), "t.stp").instances())
    e = info.value
    assert isinstance(e, SyntaxError)
    assert (e.line, e.column, e.p21_id) == (line, column, p21_id)
    assert message in e.message
    d = e.asdict()
    assert d["p21_id"] == p21_id and d["file"] == "t.stp"
    assert str(e).startswith(f"t.stp:{line}:{column}: #{p21_id}:")
    assert str(e).splitlines()[-1].index("^") == 4 + column - 1


def test_not_a_part21_file() -> None:
    with pytest.raises(Part21SyntaxError) as info:
        read_text("hello", "x.stp")
    assert (info.value.line, info.value.column) == (1, 1)


def test_deep_nesting_is_an_error_not_a_crash() -> None:
    with pytest.raises(Part21SyntaxError, match="nested deeper"):
        list(read_text(wrap("#1=A(" + "(" * 5000 + ")" * 5000 + ");")).instances())


# -- lenient --------------------------------------------------------------------


def test_lenient_keeps_the_broken_instance_as_text() -> None:
    got, r = instances("#1=A(1,2;\n#2=B();\n#3=C(#4#5);\n#4=D();", lenient=True)
    assert [(i.id, i.unreadable is not None) for i in got] == [(1, True), (2, False), (3, True), (4, False)]
    assert [(d.code, d.p21_id, d.line) for d in r.diagnostics] == [("P21-SYNTAX", 1, 6), ("P21-SYNTAX", 3, 8)]
    assert [r.text[i.start:i.end] for i in got if i.unreadable] == ["#1=A(1,2;", "#3=C(#4#5);"]
    assert got[0].name == "A" and got[0].params == [] and "expected ',' or ')'" in (got[0].unreadable or "")
    assert r.defined == 4


def test_lenient_repairs() -> None:
    got, r = instances("#1=A('curly\u2019,CW)\n#2=B('x');\n(* remark *)\n#3=C();", lenient=True)
    assert [i.id for i in got] == [1, 2, 3]
    assert got[0].params == ["curly", Enum("CW")]
    assert [d.code for d in r.diagnostics] == ["P21-CURLY-QUOTE", "P21-BARE-ENUM", "P21-MISSING-SEMICOLON",
                                               "P21-EXPRESS-REMARK"]
    assert all(d.severity == "warning" for d in r.diagnostics)


def _count_definitions(path: Path) -> int:
    """Instance definitions in a file, counted independently of the reader."""
    return len(re.findall(r"(?m)^\s*#\d+\s*=", path.read_text(encoding="utf-8")))


FAIL = sorted(P21.glob("fail_*.stp"))


@pytest.mark.parametrize("path", FAIL, ids=lambda p: p.stem)
def test_fail_fixtures_expected_reader_diagnostics(path: Path) -> None:
    expected = json.loads(path.with_suffix(".reader.json").read_text())
    with pytest.raises(Part21SyntaxError) as info:
        list(read_file(path).instances())
    assert [info.value.line, info.value.column] == expected["strict_error"]
    r = read_file(path, lenient=True)
    loaded = list(r.instances())
    got = [[d.code, d.line, d.p21_id] for d in r.diagnostics]
    assert got == expected["diagnostics"]
    repeated = [d for d in r.diagnostics if d.code == "P21-DUPLICATE-ID"]
    assert len(r.duplicate_texts) == len(repeated)
    assert _count_definitions(path) == r.defined == len(loaded) + len(repeated)


CORPUS_COUNTS = {"EXAMPLE1_FDIS_14649-11_2001.stp": 108, "EXAMPLE2_FDIS_14649-11_2001.stp": 544,
                 "EXAMPLE3_FDIS_14649-11_2001.stp": 60, "nist_toolkit_ex1.stp": 105, "nist_toolkit_ex1E.stp": 1523,
                 "ufsc_furo.p21": 60, "ufsc_TesteFinalUNBLAB.p21": 468, "ufsc_Peca_Defesa.p21": 112}


@pytest.mark.shared
@pytest.mark.parametrize("name", sorted(CORPUS_COUNTS))
def test_corpus_files_read_strictly(shared: Path, name: str) -> None:
    r = read_file(shared / "corpus" / "milling" / name)
    assert sum(1 for _ in r.instances()) == CORPUS_COUNTS[name]
    assert r.diagnostics == []


# -- fuzzing ----------------------------------------------------------------------

_PIECES = [*"#=();,$*'.\"/ \n", "#1", "#22", "=A(", "1.5", "-3", "'s'", ".T.", "B(", "/*", "*/", "ENDSEC;",
           "DATA;", "(*", "*)", "\u2019", "\\X2\\", "\\"]


@settings(max_examples=400, deadline=None)
@given(st.lists(st.sampled_from(_PIECES), max_size=40).map("".join), st.booleans())
def test_random_data_only_raises_documented_errors(data: str, lenient: bool) -> None:
    try:
        r = read_text(wrap(data), "f.stp", lenient)
        for _ in r.instances():
            pass
    except Part21SyntaxError as e:
        assert e.line >= 1 and e.column >= 1


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300))
def test_random_bytes_only_raise_documented_errors(blob: bytes) -> None:
    text = "ISO-10303-21;HEADER;" + blob.decode("latin-1")
    try:
        for _ in read_text(text, "f.stp", lenient=True).instances():
            pass
    except Part21SyntaxError:
        pass


# -- recovery at instance boundaries, huge integers (issue 26) -----------------------------------------


def test_lenient_recovers_at_the_next_instance_on_the_same_line() -> None:
    got, r = instances("#1=A('a\\Q');#2=B('b');#3=C(#2); #4=D(1,,);#5=E();", lenient=True)
    assert [(i.id, i.unreadable is not None) for i in got] == [(1, True), (2, False), (3, False), (4, True), (5, False)]
    assert [r.text[i.start:i.end] for i in got if i.unreadable] == ["#1=A('a\\Q');", "#4=D(1,,);"]
    assert [(d.code, d.p21_id) for d in r.diagnostics] == [("P21-SYNTAX", 1), ("P21-SYNTAX", 4)]


def test_a_semicolon_or_instance_start_inside_a_string_is_no_boundary() -> None:
    got, r = instances("#1=A('x;#5=Y(', ('y);#6=Z('), 'a\\Q');#2=B('b');", lenient=True)
    assert [i.id for i in got] == [1, 2]
    assert r.text[got[0].start:got[0].end] == "#1=A('x;#5=Y(', ('y);#6=Z('), 'a\\Q');"
    assert r.unreadable_texts == []


def test_an_unclosed_string_ends_its_instance_at_the_next_instance_on_the_line() -> None:
    for gap in ("", " ", "\n"):
        got, r = instances(f"#1=A('x,#9);{gap}#2=B('b');{gap}#3=C('c');", lenient=True)
        assert [i.id for i in got] == [1, 2, 3], gap
        assert r.text[got[0].start:got[0].end] == "#1=A('x,#9);"
        assert [(d.code, d.p21_id) for d in r.diagnostics] == [("P21-SYNTAX", 1)]  # nothing of #2's misreading


def test_text_that_names_no_instance_is_kept_and_reported() -> None:
    got, r = instances("#1=B('b');#=FOO(1);#999=BAR(2); junk #3=C();", lenient=True)
    assert [i.id for i in got] == [1, 999, 3]
    assert [r.text[t.start:t.end] for t in r.unreadable_texts] == ["#=FOO(1);", "junk"]
    assert [(t.line, t.column) for t in r.unreadable_texts] == [(6, 11), (6, 33)]
    assert [(d.code, d.p21_id, d.column) for d in r.diagnostics] == [("P21-SYNTAX", None, 11), ("P21-SYNTAX", None, 33)]


def test_an_instance_after_endsec_on_the_same_line_is_no_truncation() -> None:
    text = wrap("#1=B('b');").replace("ENDSEC;\nEND", "ENDSEC;#2=C(#1);END")
    r = read_text(text, "t.stp", lenient=True)
    assert [i.id for i in r.instances()] == [1, 2]
    assert [(d.code, d.p21_id) for d in r.diagnostics] == [("P21-OUTSIDE-SECTION", 2)]


def test_a_missing_endsec_is_a_warning_not_a_truncation() -> None:
    text = wrap("#1=B('b');").replace("ENDSEC;\nEND", "END")
    with pytest.raises(Part21SyntaxError, match="ENDSEC"):
        list(read_text(text, "t.stp").instances())
    r = read_text(text, "t.stp", lenient=True)
    assert [i.id for i in r.instances()] == [1]
    assert [(d.code, d.severity) for d in r.diagnostics] == [("P21-ENDSEC-MISSING", "warning")]


def test_text_after_the_end_marker_is_kept_and_reported() -> None:
    text = wrap("#1=B('b');") + "#2=C(#1);\n"
    with pytest.raises(Part21SyntaxError, match="after END-ISO-10303-21") as e:
        list(read_text(text, "t.stp").instances())
    assert (e.value.line, e.value.column) == (9, 1)
    r = read_text(text, "t.stp", lenient=True)
    assert [i.id for i in r.instances()] == [1]
    assert [r.text[t.start:t.end] for t in r.unreadable_texts] == ["#2=C(#1);"]
    assert [(d.code, d.line) for d in r.diagnostics] == [("P21-SYNTAX", 9)]


BIG = "9" * 5000


@pytest.mark.parametrize("data,p21_id,column", [
    (f"#1=B({BIG});", 1, 6),  # a value
    (f"#1=B(-{BIG}.5);#2=C((#{BIG}));", 2, 5017),  # a reference (the huge REAL is read: a double's infinity)
    (f"#{BIG}=B(1);", None, 1),  # an instance name
])
def test_an_integer_python_cannot_read_is_a_positioned_error(data: str, p21_id: int | None, column: int) -> None:
    with pytest.raises(Part21SyntaxError, match="5000 digits") as e:
        list(read_text(wrap(data + "\n#7=D();"), "t.stp").instances())
    assert (e.value.line, e.value.column, e.value.p21_id) == (6, column, p21_id)
    assert "integer" in " ".join(e.value.expected)
    got, r = instances(data + "\n#7=D();", lenient=True)
    assert [d.code for d in r.diagnostics] == ["P21-SYNTAX"] and "5000 digits" in r.diagnostics[0].message
    assert got[-1].id == 7  # reading goes on
    kept = [r.text[i.start:i.end] for i in got if i.unreadable] + [r.text[t.start:t.end] for t in r.unreadable_texts]
    assert [k for k in kept if BIG in k]  # the text is kept


def test_defined_ids_skip_an_instance_name_python_cannot_read() -> None:
    from stepnc_graph.part21.reader import defined_ids

    assert defined_ids(f"#1=A();#{BIG}=B();#2=C();") == {1, 2}


def test_a_huge_instance_name_in_the_reference_section_is_a_positioned_error() -> None:
    text = wrap("#1=B('b');").replace("DATA;", f"REFERENCE;\n#{BIG}=<x.stp#a>;\nENDSEC;\nDATA;")
    with pytest.raises(Part21SyntaxError, match="5000 digits") as e:
        read_text(text, "t.stp", lenient=True)
    assert (e.value.line, e.value.column) == (6, 1)


def test_many_unreadable_instances_are_read_in_linear_time() -> None:
    """Each recovery reports a position before the one it last asked for: stepping back must not
    recount the file from its start (40,000 broken instances took 25 CPU s that way, 1.4 now)."""
    import time

    body = "".join(f"#{i}=A('{'x' * 40}',\n 1,,2);\n" for i in range(1, 40_001))
    started = time.process_time()
    got, r = instances(body, lenient=True)
    assert len(got) == 40_000 and all(i.unreadable for i in got) and len(r.diagnostics) == 40_000
    assert r.diagnostics[-1].line == 5 + 2 * 40_000 - 1
    assert time.process_time() - started < 10  # CPU time: a busy machine cannot fail it
