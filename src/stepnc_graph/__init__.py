"""stepnc-graph: ISO 14649 (STEP-NC) process data as a knowledge graph.

The Python API (see :mod:`stepnc_graph.api`)::

    import stepnc_graph as sg
    store = sg.open_store(memory=True)
    [result] = sg.load(store, ["examples/shaft_two_setups.stp"])
    sg.export(store, "ttl", result.graph)
    sg.query(store, "workingsteps-by-tool-type", tool_type="grooving_tool").rows
"""

__version__ = "0.1.0"

from stepnc_graph.api import (  # noqa: E402
    GraphInfo,
    LoadResult,
    QueryResult,
    export,
    info,
    load,
    open_store,
    query,
    unload,
)

__all__ = ["GraphInfo", "LoadResult", "QueryResult", "__version__", "export", "info", "load", "open_store", "query",
           "unload"]
