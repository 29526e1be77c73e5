"""The architecture holds: layers that only import downwards, no import cycle, no caller testing
which store it has, modules and classes of a size one can read (figures by tools/architecture.py)."""

from __future__ import annotations

import importlib.util
import sys

import pytest

from conftest import ROOT


@pytest.fixture(scope="module")
def figures():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("architecture", ROOT / "tools" / "architecture.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["architecture"] = module
    spec.loader.exec_module(module)
    return module.measure()


def test_no_import_cycle_even_through_function_level_imports(figures) -> None:  # type: ignore[no-untyped-def]
    assert len(figures.cycles) == 0, figures.cycles


def test_imports_only_point_down_the_layers(figures) -> None:  # type: ignore[no-untyped-def]
    assert len(figures.upward) == 0, figures.upward


def test_callers_ask_the_store_contract_never_the_back_end(figures) -> None:  # type: ignore[no-untyped-def]
    assert len(figures.type_tests) == 0, figures.type_tests


def test_modules_and_classes_stay_readable(figures) -> None:  # type: ignore[no-untyped-def]
    assert len(figures.large_modules) <= 14, figures.large_modules
    assert len(figures.large_classes) <= 4, figures.large_classes
