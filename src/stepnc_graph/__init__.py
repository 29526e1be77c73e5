"""stepnc-graph: ISO 14649 (STEP-NC) process data as a knowledge graph.

The Python API (see :mod:`stepnc_graph.api`)::

    import stepnc_graph as sg
    store = sg.open_store(memory=True)
    [result] = sg.load(store, ["examples/shaft_two_setups.stp"])
    sg.export(store, "ttl", result.graph)
    sg.query(store, "workingsteps-by-tool-type", tool_type="grooving_tool").rows

The API names are imported on first use (module ``__getattr__``), so that
``import stepnc_graph.cli`` -- every command, even ``--help`` -- does not pay
for the store, the loader and the exporters before it needs them.
"""

from __future__ import annotations

import sys
import types
from typing import TYPE_CHECKING, Any

from stepnc_graph.core.version import __version__

if TYPE_CHECKING:
    from stepnc_graph.api import (
        Compacted,
        GraphInfo,
        LinkResult,
        LoadResult,
        Plan,
        QueryResult,
        build_plan,
        compact,
        export,
        info,
        link,
        load,
        open_store,
        query,
        unload,
        validate,
    )

__all__ = ["Compacted", "GraphInfo", "LinkResult", "LoadResult", "Plan", "QueryResult", "__version__", "build_plan",
           "compact", "export", "info", "link", "load", "open_store", "query", "unload", "validate"]


class _Package(types.ModuleType):
    """This package's module type: the submodule ``stepnc_graph.exporting.exporter`` never hides ``export()``.

    Importing a submodule binds it on its package under its name. When the API
    was imported here eagerly, ``export`` was re-bound to the function right
    after; imported lazily, the submodule (imported by the loader, the CLI, ...)
    would take the name for good, so that binding is refused here.
    """

    def __setattr__(self, name: str, value: Any) -> None:
        if name in __all__ and isinstance(value, types.ModuleType):
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name: str) -> Any:
    if name in __all__:
        from stepnc_graph import api

        value = getattr(api, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
