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
    assert figures.large_modules == [], figures.large_modules
    assert figures.large_classes == [], figures.large_classes


def _documented_modules() -> set[str]:
    """The files docs/architecture.md's folder tree names, as paths under src/stepnc_graph."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    tree = text.split("```\nsrc/stepnc_graph/\n", 1)[1].split("```", 1)[0]
    found, package = set(), ""
    for line in tree.splitlines():
        indent, entry = len(line) - len(line.lstrip()), line.strip().split("  ")[0]
        if indent == 2 and entry.endswith("/"):
            package = entry
        elif indent == 2:
            found.add(entry)
        elif indent == 4 and entry.endswith((".py", ".py,")):
            found.update(package + name.strip() for name in entry.split(",") if name.strip())
    return found


def test_the_documented_tree_is_the_package() -> None:
    package = ROOT / "src" / "stepnc_graph"
    actual = {str(p.relative_to(package)) for p in package.rglob("*.py")}
    optional = {name for name in actual if name.endswith(("/__init__.py", "/__main__.py"))}
    documented = _documented_modules()
    assert documented - actual == set()  # nothing named that is not there
    assert actual - optional - documented == set()  # every module is named, with its role
