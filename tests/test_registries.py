"""Registries instead of lists (:mod:`stepnc_graph.core.formats`, :mod:`stepnc_graph.generators.registry`):
the CLI's ``--format`` choices, the loaders' and exporters' dispatch and the artefact build read
one table each, and the CLI reads its choices without importing what implements them."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

import stepnc_graph as sg
from stepnc_graph.cli import main
from stepnc_graph.core.errors import StepncGraphError
from stepnc_graph.core.formats import (
    EXPORT_FORMATS,
    INPUT_FORMATS,
    QUERY_RESULT_FORMATS,
    export_format_names,
    input_format,
    input_suffixes,
)
from stepnc_graph.generators.registry import GENERATORS, generator
from stepnc_graph.loading.sources import plan_sources

from conftest import ROOT
from test_startup import imported_by

EXAMPLE = ROOT / "examples" / "shaft_two_setups.stp"


def _choices(command: str) -> list[str]:
    help_text = CliRunner().invoke(main, [command, "--help"], terminal_width=200).output
    line = next(ln for ln in help_text.splitlines() if "--format" in ln)
    return line.split("[", 1)[1].split("]", 1)[0].split("|")


def test_the_cli_offers_the_registered_formats() -> None:
    assert _choices("export") == list(export_format_names())
    assert _choices("query") == list(QUERY_RESULT_FORMATS)


def test_the_choices_come_without_the_exporter() -> None:
    code, modules = imported_by(["export", "--help"])
    assert code == 0
    assert "stepnc_graph.exporting.exporter" not in modules and "pyoxigraph" not in modules


def test_every_registered_export_format_exports() -> None:
    with sg.open_store(memory=True) as store:
        [result] = sg.load(store, [EXAMPLE])
        for fmt in EXPORT_FORMATS:
            data = sg.export(store, fmt.name, result.graph)
            assert data, fmt.name
    with pytest.raises(StepncGraphError, match="use one of " + ", ".join(export_format_names())):
        with sg.open_store(memory=True) as store:
            sg.export(store, "rdfxml")


def test_a_directory_load_finds_every_registered_input_suffix(tmp_path: Path) -> None:
    for k, suffix in enumerate(input_suffixes()):
        (tmp_path / f"p{k}{suffix.upper() if k % 2 else suffix}").write_text("x")
    (tmp_path / "notes.txt").write_text("x")
    found = [Path(s.path).suffix.lower() for s in plan_sources([tmp_path], "urn:x:") if s.path is not None]
    assert sorted(found) == sorted(input_suffixes())
    assert {input_format(Path(f"a{s}")).name for s in input_suffixes()} == {f.name for f in INPUT_FORMATS}  # type: ignore[union-attr]


def test_generators_are_found_by_name() -> None:
    assert [g.name for g in GENERATORS] == ["owl", "generic", "p21", "context", "shacl", "html", "pyvocab"]
    assert generator("shacl").directory == "shapes"
    with pytest.raises(KeyError, match="known: owl"):
        generator("uml")
