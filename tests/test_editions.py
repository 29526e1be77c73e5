"""Other editions of the ISO 14649 schemas: the ISO/FDIS 14649-10/-11 of 2001 as a catalogue of its
own, its files as tools/author_fdis_2001.py writes them, and the table that tells editions apart."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from stepnc_graph.express import ExpressSyntaxError, parse_file
from stepnc_graph.schema import build_model
from stepnc_graph.schema.catalog import edition_directory, load_edition_model
from stepnc_graph.schema.editions import TABLE_FILE, fitting_editions, read_table
from stepnc_graph.schema.errors import SchemaErrors

from conftest import ROOT

sys.path.insert(0, str(ROOT / "tools"))
import author_fdis_2001  # noqa: E402
import edition_census  # noqa: E402


@pytest.fixture(scope="module")
def fdis2001():  # type: ignore[no-untyped-def]
    return load_edition_model("fdis2001")


def test_fdis2001_resolves_as_an_edition_of_its_own(fdis2001) -> None:  # type: ignore[no-untyped-def]
    catalog, model = fdis2001
    assert catalog.directory == edition_directory("fdis2001")
    assert sorted(model.schemas) == ["machining_schema", "milling_schema"]
    assert model.schemas["milling_schema"].edition == "ISO/FDIS 14649-11:2001"
    assert len(model.entities) == 358
    # the 2001 tool model and argument lists
    assert [s.name for s in model.part21_attributes("tool_dimension")][:2] == ["diameter", "tool_top_angle"]
    assert len(model.part21_attributes("boring_tool")) == 5
    assert "center_drill" in model.entities and "centerdrill" not in model.entities
    # repairs 3 and 4 of milling_schema.exp
    stepover = model.attribute("bidirectional", "stepover_direction")
    assert stepover is not None and stepover.optional and str(stepover.type) == "left_or_right"
    assert [r.label for r in model.entity("bottom_and_side_rough_milling").where_rules] == ["wr1", "wr2"]
    # the 2001 resources are ISO's: representation_item declares name
    assert [s.name for s in model.part21_attributes("cartesian_point")] == ["name", "coordinates"]
    assert model.part21_attributes("cartesian_point")[0].attribute.entity == "representation_item"


@pytest.mark.shared
def test_fdis2001_files_are_what_the_tool_writes(shared: Path, tmp_path: Path) -> None:
    written = author_fdis_2001.author(shared / "reference" / "express", tmp_path)
    for path in written:
        assert path.read_text(encoding="utf-8") == (edition_directory("fdis2001") / path.name).read_text(
            encoding="utf-8"), path.name


@pytest.mark.shared
@pytest.mark.parametrize("left_out", range(5))
def test_each_repair_is_needed(shared: Path, tmp_path: Path, left_out: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """Without any one of the repairs the source does not parse or does not resolve."""
    repairs = [(name, i) for name, (_, _, rs) in author_fdis_2001.SOURCES.items() for i in range(len(rs))]
    assert len(repairs) == 5
    name, index = repairs[left_out]
    source, title, rs = author_fdis_2001.SOURCES[name]
    monkeypatch.setitem(author_fdis_2001.SOURCES, name, (source, title, rs[:index] + rs[index + 1:]))
    written = author_fdis_2001.author(shared / "reference" / "express", tmp_path)
    with pytest.raises((ExpressSyntaxError, SchemaErrors)):
        build_model([p for path in written for p in parse_file(path)])


def test_edition_table_tells_2001_from_2002() -> None:
    table = read_table((ROOT / "ontology" / TABLE_FILE).read_text(encoding="utf-8"))
    assert set(table["editions"]) == {"2002", "fdis2001"}
    assert table["only_in"]["fdis2001"] == ["center_drill", "explicit", "milling_tool_body", "threading_tool",
                                            "tool_dimension"]
    assert {"centerdrill", "milling_tool_dimension", "explicit_strategy"} <= set(table["only_in"]["2002"])
    assert table["parameters_differ"]["boring_tool"] == {"2002": 6, "fdis2001": 5}
    assert fitting_editions(table, "BORING_TOOL", 5) == ("fdis2001",)
    assert fitting_editions(table, "BORING_TOOL", 6) == ("2002",)
    assert fitting_editions(table, "CARTESIAN_POINT", 2) == ("2002", "fdis2001")
    assert fitting_editions(table, "NO_SUCH_ENTITY", 1) == ()


def test_census_of_a_program_by_edition(tmp_path: Path) -> None:
    program = tmp_path / "mixed.stp"
    program.write_text(
        "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('m','',(''),(''),'','','');\n"
        "FILE_SCHEMA(('MACHINING_SCHEMA','MILLING_SCHEMA'));\nENDSEC;\nDATA;\n"
        "#1=CARTESIAN_POINT('',(0.,0.,0.));\n"
        "#2=TOOL_DIMENSION(10.,$,$,$,$,$,$);\n"
        "#3=BORING_TOOL(#2,1,$,$,$);\n"
        "#4=BORING_TOOL(#2,1,$,$,$,$);\n"
        "#5=HELIX('',#1,7.2,8.);\n"
        "ENDSEC;\nEND-ISO-10303-21;\n", encoding="utf-8")
    table = read_table((ROOT / "ontology" / TABLE_FILE).read_text(encoding="utf-8"))
    found = edition_census.census(program, table)
    assert dict(found["both"]) == {"CARTESIAN_POINT(2)": 1}
    assert dict(found["fdis2001 only"]) == {"TOOL_DIMENSION(7)": 1, "BORING_TOOL(5)": 1}
    assert dict(found["2002 only"]) == {"BORING_TOOL(6)": 1}
    assert dict(found["neither"]) == {"HELIX(4)": 1}
