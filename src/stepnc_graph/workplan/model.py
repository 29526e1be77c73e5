"""The plan's data: the execution steps and the things they name (workingsteps, features, tools,
setups, workplans, operations, technologies), tool changes and precedence errors, and the error a
plan reports. Plain values, read from the store by :mod:`stepnc_graph.workplan.reading` and
analysed by :class:`stepnc_graph.workplan.analyses.Plan`."""

from __future__ import annotations

from dataclasses import dataclass, field

from stepnc_graph.core.errors import StepncGraphError


class PlanError(StepncGraphError, ValueError):
    """No such program in the store, or a store the plan cannot be read from."""


@dataclass(frozen=True)
class Thing:
    """A workingstep, feature, tool, setup, workplan, ...: its IRI, its_id and #id."""

    iri: str
    label: str
    ref: str
    cls: str = ""


@dataclass(frozen=True)
class Technology:
    """An operation's technology: #id, class and the numbers it states (``values``: attribute name
    and value, the shortest text of the number; its own attributes first, then those of the
    entities it names -- a turning technology's spindle speed --, each in Part 21 parameter order)."""

    iri: str
    ref: str
    cls: str
    values: tuple[tuple[str, str], ...] = ()

    def text(self, sep: str = " ") -> str:
        """``feedrate=0.25 speed=180 ...`` (the class when it states no number)."""
        return sep.join(f"{k}={v}" for k, v in self.values) or self.cls


#: the legend's names for steps whose tool has no body, and steps without a tool
NO_TOOL_BODY, NO_TOOL = "no tool body", "no tool"


@dataclass
class Step:
    """One step of the execution order."""

    order: int
    workingstep: Thing
    workplan: Thing | None
    setup: Thing | None
    tool: Thing | None
    operation: Thing | None
    features: list[Thing] = field(default_factory=list)
    kind: str = ""  # "rough", "finish" or ""
    #: the first step of a root of the execution order (a project's main workplan): the tool it
    #: takes is loaded, not changed (the derived layer's rule, see stepnc_graph.loading.derive)
    starts_root: bool = False
    technology: Technology | None = None
    #: the class of the tool's body as the program's graph types it (``general_turning_tool``,
    #: ``twist_drill``, ...), :data:`NO_TOOL_BODY` or :data:`NO_TOOL`
    tool_body: str = NO_TOOL


@dataclass(frozen=True)
class ToolChange:
    order: int
    workingstep: Thing
    before: Thing
    after: Thing


@dataclass(frozen=True)
class Precedence:
    """A finishing step that runs before a roughing step on the same feature."""

    feature: Thing
    finish: int
    rough: int

