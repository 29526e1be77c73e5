"""The workplan of a loaded program: the one place to import it from (the CLI, the API, tests).

:func:`build_plan` reads a program's plan from the store (:mod:`~stepnc_graph.workplan.reading`);
the :class:`Plan` it returns holds the execution steps (:mod:`~stepnc_graph.workplan.model`), the
analyses, the summary, GraphML of its networkx graph (:mod:`~stepnc_graph.workplan.analyses`) and
the SVG picture (:class:`PlanPicture`, :mod:`~stepnc_graph.workplan.picture`; PNG with the ``png``
extra).
"""

from stepnc_graph.workplan.analyses import Plan
from stepnc_graph.workplan.model import (
    NO_TOOL,
    NO_TOOL_BODY,
    PlanError,
    Precedence,
    Step,
    Technology,
    Thing,
    ToolChange,
)
from stepnc_graph.workplan.picture import PALETTE, Block, PlanPicture, blocks, png
from stepnc_graph.workplan.reading import build_plan

__all__ = ["NO_TOOL", "NO_TOOL_BODY", "PALETTE", "Block", "Plan", "PlanError", "PlanPicture", "Precedence", "Step",
           "Technology", "Thing", "ToolChange", "blocks", "build_plan", "png"]
