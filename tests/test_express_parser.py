"""EXPRESS front end: pass/fail fixtures, positions, grammar fixes, robustness."""

from __future__ import annotations

import json
import time
from pathlib import Path

import express_schema.parse as ast
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stepnc_graph.express import ExpressSyntaxError, parse_file, parse_text
from stepnc_graph.express._patched_parser import GroupRef, IndexRangeExpr
from stepnc_graph.express.comments import blank_comments

from conftest import FIXTURES

FAIL = sorted((FIXTURES / "express").glob("fail_*.exp"))


@pytest.mark.parametrize("path", FAIL, ids=lambda p: p.stem)
def test_fail_fixtures_report_expected_position(path: Path) -> None:
    expected = json.loads(path.with_suffix(".expected.json").read_text())
    with pytest.raises(ExpressSyntaxError) as info:
        parse_file(path)
    e = info.value
    assert isinstance(e, SyntaxError)
    assert (e.line, e.column) == (expected["line"], expected["column"])
    assert expected["message"] in e.message
    assert e.filename == str(path)
    rendered = str(e)
    assert rendered.startswith(f"{path}:{expected['line']}:{expected['column']}:")
    caret_line = rendered.splitlines()[-1]
    assert caret_line.index("^") == 4 + expected["column"] - 1
    assert e.asdict()["line"] == expected["line"]
    assert e.asdict()["source_line"] == path.read_text().splitlines()[expected["line"] - 1]


def test_pass_fixture_parses_two_schemas_with_positions() -> None:
    parsed = parse_file(FIXTURES / "express" / "pass_remarks_and_qualifiers.exp")
    assert [p.name for p in parsed] == ["remarks_and_qualifiers", "second_schema"]
    first = parsed[0].tree
    entity = {str(e.identifier): e for e in first.entity_declarations}["named_item"]
    # 0-based in the library's AST: line 8, column 0 is "ENTITY named_item;" on line 8 (1-based).
    assert (int(entity.position.lineno) + 1, int(entity.position.column) + 1) == (8, 1)


def _walk(node: object, seen: list[object]) -> None:
    seen.append(node)
    for value in vars(node).values() if hasattr(node, "__dict__") else ():
        items = value if isinstance(value, (list, tuple)) else [value]
        for item in items:
            if isinstance(item, ast.Node):
                _walk(item, seen)


def test_grammar_fixes_produce_nodes() -> None:
    parsed = parse_file(FIXTURES / "express" / "pass_remarks_and_qualifiers.exp")
    nodes: list[object] = []
    _walk(parsed[0].tree, nodes)
    ranges = [n for n in nodes if isinstance(n, IndexRangeExpr)]
    groups = [n for n in nodes if isinstance(n, GroupRef)]
    assert len(ranges) == 1 and isinstance(ranges[0].index_2, ast.IntegerLiteral)
    assert len(groups) == 1 and str(groups[0].group_qualifier) == "named_item"


def test_plain_index_and_qualified_attribute_still_parse() -> None:
    text = "SCHEMA s; ENTITY a; l : LIST OF INTEGER; WHERE w : SELF\\a.l[1] > 0; END_ENTITY; END_SCHEMA;"
    nodes: list[object] = []
    _walk(parse_text(text)[0].tree, nodes)
    assert any(isinstance(n, ast.IndexExpr) for n in nodes)
    assert any(isinstance(n, ast.QualifiedAttributeRef) for n in nodes)


def test_blanking_keeps_every_position() -> None:
    text = "A (* x\n (* y *) \n*) B -- c 'q\nC 'it''s (* no remark *)' D"
    clean = blank_comments(text)
    assert len(clean) == len(text)
    assert [i for i, c in enumerate(clean) if c == "\n"] == [i for i, c in enumerate(text) if c == "\n"]
    assert clean.split() == ["A", "B", "C", "'it''s", "(*", "no", "remark", "*)'", "D"]


_PIECES = [*"(*)-'\"\n aZ;:[]\\.,=<>0123456789", "SCHEMA ", "END_SCHEMA", "ENTITY ", "END_ENTITY",
           " WHERE ", "SELF", "TYPE ", "END_TYPE", "SUBTYPE OF"]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(_PIECES), max_size=60).map("".join))
def test_random_text_raises_only_express_syntax_error(text: str) -> None:
    try:
        parse_text(text)
    except ExpressSyntaxError as e:
        assert e.line >= 1 and e.column >= 1


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=200))
def test_blank_comments_preserves_length_and_line_breaks(text: str) -> None:
    clean = blank_comments(text)
    assert len(clean) == len(text)
    for a, b in zip(text, clean, strict=True):
        if a in "\r\n":
            assert b == a


LARGE = ["IFC4.exp", "AP214E3_2010.exp", "ap203e2_mim_lf.exp", "ap238_aim_long.exp"]


@pytest.mark.shared
@pytest.mark.parametrize("name", LARGE)
def test_large_real_schemas_parse(shared: Path, name: str) -> None:
    started = time.perf_counter()
    schemas = parse_file(shared / "reference" / "express-other" / name)
    assert len(schemas) == 1
    assert len(schemas[0].tree.entity_declarations) > 300
    assert time.perf_counter() - started < 120  # a hang guard, not a speed target (see bench/)
