"""One error root: every error stepnc-graph reports to a user derives from
:class:`~stepnc_graph.core.errors.StepncGraphError`, which is what the CLI catches (exit 2), so a
new error class needs no list of the CLI's to be reported cleanly."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import pytest

import stepnc_graph
from stepnc_graph.core.errors import StepncGraphError

#: exceptions that steer control flow inside one module and never reach a user (each is caught
#: where it is raised: a stale cache is rebuilt, a shape that cannot be translated is run by the
#: engine, a value that does not fit a type is kept raw)
INTERNAL = {"StaleCache", "StaleChecks", "Mismatch", "Untranslatable"}


def _error_classes() -> dict[str, type[BaseException]]:
    found: dict[str, type[BaseException]] = {}
    for info in pkgutil.walk_packages(stepnc_graph.__path__, "stepnc_graph."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for name, value in vars(module).items():
            if (inspect.isclass(value) and issubclass(value, BaseException) and not issubclass(value, Warning)
                    and value.__module__ == info.name and not name.startswith("_")):
                found[f"{info.name}.{name}"] = value
    return found


def test_every_user_facing_error_derives_from_the_root() -> None:
    classes = _error_classes()
    assert len(classes) >= 20  # the walk found the package's errors
    outside = sorted(name for name, cls in classes.items()
                     if not issubclass(cls, StepncGraphError) and name.rpartition(".")[2] not in INTERNAL)
    assert outside == []


@pytest.mark.parametrize("name", ["SourceError", "GraphNameError", "QueryError", "DataError", "ExportError"])
def test_the_root_keeps_the_builtin_bases(name: str) -> None:
    """Callers that caught ``ValueError`` still catch these (the API does not change)."""
    [cls] = [c for n, c in _error_classes().items() if n.endswith("." + name)]
    assert issubclass(cls, ValueError) and issubclass(cls, StepncGraphError)


def test_the_cli_reports_the_root_and_no_list() -> None:
    from stepnc_graph.cli.common import user_errors

    assert StepncGraphError in user_errors()
    assert all(not issubclass(e, StepncGraphError) for e in user_errors() if e is not StepncGraphError)
