"""The resolved model: construct by construct on tiny schemas, then the ISO 14649 schemas."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stepnc_graph.express import parse_file, parse_text
from stepnc_graph.schema import SchemaErrors, SchemaModel, build_model
from stepnc_graph.schema.model import AggregateType, BaseType, NamedType, SimpleType

from conftest import FIXTURES


def model_of(text: str) -> SchemaModel:
    return build_model(parse_text(text, "tiny.exp"))


DIAMOND = """
SCHEMA tiny;
TYPE length_measure = REAL; END_TYPE;
TYPE positive_length = length_measure; WHERE wr1 : SELF > 0.0; END_TYPE;
TYPE colour = ENUMERATION OF (red, green); END_TYPE;
TYPE inner = SELECT (leaf_a, positive_length); END_TYPE;
TYPE outer = SELECT (inner, colour, leaf_b); END_TYPE;
ENTITY Top ABSTRACT SUPERTYPE OF (ONEOF(leaf_a, leaf_b) ANDOR mixin);
  id : STRING;
END_ENTITY;
ENTITY leaf_a SUBTYPE OF (top);
  a : OPTIONAL positive_length;
END_ENTITY;
ENTITY leaf_b SUBTYPE OF (top);
  b : LIST [1:?] OF SET [2:3] OF leaf_a;
END_ENTITY;
ENTITY mixin SUBTYPE OF (top);
  m : outer;
END_ENTITY;
ENTITY both SUBTYPE OF (leaf_a, mixin);
  own : BOOLEAN;
DERIVE
  SELF\\leaf_a.a : positive_length := 1.0;
  twice : REAL := 2.0 * 1.0;
INVERSE
  users : SET [0:?] OF user FOR target;
UNIQUE
  ur1 : own;
END_ENTITY;
ENTITY user;
  target : both;
END_ENTITY;
END_SCHEMA;
"""


@pytest.fixture(scope="module")
def diamond() -> SchemaModel:
    return model_of(DIAMOND)


def test_names_are_case_insensitive(diamond: SchemaModel) -> None:
    assert diamond.entity("TOP").name == "top"
    assert "Leaf_A" in diamond
    assert diamond.is_subtype("BOTH", "Top")


def test_part21_order_with_multiple_inheritance_and_derived_redeclaration(diamond: SchemaModel) -> None:
    slots = diamond.part21_attributes("both")
    assert [(s.attribute.entity, s.name) for s in slots] == [
        ("top", "id"), ("leaf_a", "a"), ("mixin", "m"), ("both", "own")]
    assert [s.derived for s in slots] == [False, True, False, False]
    assert [s.index for s in slots] == [0, 1, 2, 3]
    # Inherited top.id appears once although both supertypes inherit it.
    assert diamond.part21_attributes("leaf_a")[1].optional is True


def test_abstract_supertype_expression(diamond: SchemaModel) -> None:
    top = diamond.entity("top")
    assert top.abstract
    assert str(top.supertype_expr) == "(ONEOF(leaf_a, leaf_b) ANDOR mixin)"
    assert sorted(top.supertype_expr.names()) == ["leaf_a", "leaf_b", "mixin"]  # type: ignore[union-attr]
    assert diamond.subtypes("top") == ("leaf_a", "leaf_b", "mixin")
    assert diamond.all_subtypes("top") == ("both", "leaf_a", "leaf_b", "mixin")
    assert diamond.ancestors("both") == ("leaf_a", "top", "mixin")


def test_attributes_kinds_and_types(diamond: SchemaModel) -> None:
    both = diamond.entity("both")
    kinds = {a.name: a.kind for a in both.attributes}
    assert kinds == {"own": "explicit", "twice": "derived", "users": "inverse"}
    users = next(a for a in both.attributes if a.name == "users")
    assert users.inverse_of == ("user", "target")
    assert users.type == AggregateType("SET", NamedType("user"), 0, None)
    assert next(a for a in both.attributes if a.name == "twice").expression == "2.0 * 1.0"
    assert both.unique_rules[0].attributes == ("own",)
    b = diamond.attribute("leaf_b", "b")
    assert b is not None and str(b.type) == "LIST [1:?] OF SET [2:3] OF leaf_a"
    assert diamond.aggregate_depth(b.type) == 2
    assert [a.name for a in diamond.all_attributes("both")][:2] == ["id", "a"]


def test_defined_types_select_closure_and_enumeration(diamond: SchemaModel) -> None:
    chain, base = diamond.underlying_chain("positive_length")
    assert chain == ["positive_length", "length_measure"] and base == SimpleType(BaseType.REAL)
    assert diamond["positive_length"].where_rules[0].source == "SELF > 0.0"  # type: ignore[union-attr]
    assert diamond.select_closure("outer") == ("colour", "leaf_a", "leaf_b", "positive_length")
    assert diamond["colour"].items == ("red", "green")  # type: ignore[union-attr]
    assert diamond.kind_of("outer") == "select" and diamond.kind_of("colour") == "enumeration"


def test_interface_chain_and_alias() -> None:
    m = build_model(parse_file(FIXTURES / "schema" / "pass_interface_chain.exp"))
    rod = m.entity("rod")
    assert rod.attributes[0].type == NamedType("len")
    assert m.resolve("len", "a") is m["length_measure"]
    assert m.resolve("length_measure", "a") is None  # only the alias is visible in a


FAIL = sorted((FIXTURES / "schema").glob("fail_*.exp"))


@pytest.mark.parametrize("path", FAIL, ids=lambda p: p.stem)
def test_schema_error_fixtures(path: Path) -> None:
    expected = json.loads(path.with_suffix(".expected.json").read_text())
    with pytest.raises(SchemaErrors) as info:
        build_model(parse_file(path))
    got = [(e.pos.line if e.pos else None, e.message) for e in info.value.errors]
    assert len(got) == len(expected), got
    for (line, message), want in zip(got, expected, strict=True):
        assert line == want["line"] and want["message"] in message, (line, message)
    assert info.value.errors[0].asdict()["file"] == str(path)


# -- the project's ISO 14649 schemas -------------------------------------------


def test_project_schemas_resolve(iso_model) -> None:  # type: ignore[no-untyped-def]
    catalog, model = iso_model
    assert set(model.schemas) >= {"machining_schema", "milling_schema", "milling_tool_schema",
                                  "turning_schema", "turning_machine_tool_schema",
                                  "turning_specific_feature_schema"}
    assert not {"machine_tool", "machine_tool_specification"} & set(model.declarations)  # no Bath model


def test_seed_references_resolve_to_parts_10_and_11(iso_model) -> None:  # type: ignore[no-untyped-def]
    _, model = iso_model
    for name, schema in [("thread", "machining_schema"), ("round_hole", "machining_schema"),
                         ("approach_retract_strategy", "milling_schema"),
                         ("drilling_type_operation", "milling_schema"),
                         ("process_model_list", "milling_schema")]:
        assert model.resolve(name, "turning_schema") is model[name]
        assert model[name].schema == schema


def test_machining_operation_part21_order(iso_model) -> None:  # type: ignore[no-untyped-def]
    _, model = iso_model
    names = [s.name for s in model.part21_attributes("facing_rough")]
    assert names == ["its_toolpath", "its_tool_direction", "its_id", "retract_plane", "start_point", "its_tool",
                     "its_technology", "its_machine_functions", "approach", "retract", "its_machining_strategy",
                     "x_return_amount", "z_return_amount", "allowance"]
    assert model.entity("facing_rough").where_rules[0].source == "EXISTS(SELF. allowance) AND (SELF. allowance >=0.0)"


def test_turning_tool_constructs(iso_model) -> None:  # type: ignore[no-untyped-def]
    _, model = iso_model
    body = model.entity("turning_machine_tool_body")
    assert body.abstract and body.supertypes == ("tool_body",)
    assert sorted(body.supertype_expr.names()) == sorted(  # type: ignore[union-attr]
        ["general_turning_tool", "knurling_tool", "turning_threading_tool", "grooving_tool",
         "user_defined_turning_tool"])
    assert model["knurl_pattern"].items == ("straight", "diagonal", "diamond")  # type: ignore[union-attr]
    assert model.select_closure("speed_select_type") == ("const_cutting_speed", "const_spindle_speed")
    assert model.clause("outer_diameter") == "5.2.2.1"
    assert model.clause("knurl_pattern") == "4.3.4.1"
    ws = model.attribute("turning_workingstep", "its_features")
    assert ws is not None and str(ws.type) == "LIST [2:?] OF manufacturing_feature"


def test_negative_and_expression_bounds() -> None:
    m = model_of("SCHEMA s; CONSTANT n : INTEGER := 3; END_CONSTANT; ENTITY e; "
                 "a : ARRAY [-1:1] OF OPTIONAL REAL; b : LIST [1:n] OF INTEGER; END_ENTITY; END_SCHEMA;")
    a = m.attribute("e", "a")
    b = m.attribute("e", "b")
    assert a is not None and a.type == AggregateType("ARRAY", SimpleType(BaseType.REAL), -1, 1, optional_elements=True)
    assert b is not None and isinstance(b.type, AggregateType) and b.type.upper is None and b.type.bound_text == "1:n"
