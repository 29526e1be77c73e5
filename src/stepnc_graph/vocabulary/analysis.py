"""The analysis terms stepnc-graph adds to ISO 14649, as data.

The analysis vocabulary (:data:`ANALYSIS_CLASSES`, :data:`ANALYSIS_PROPERTIES`)
names what ISO 14649 leaves implicit: it has ``facing_rough`` and
``contouring_rough`` but no class of roughing operations; it orders
workingsteps only through nested ``LIST``s. These definitions are the single
source for ``ontology/analysis.ttl`` (generated, :mod:`stepnc_graph.generators.generic`),
the HTML reference and the derived layer (:mod:`stepnc_graph.loading.derive`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from stepnc_graph.schema.view import SchemaModel


@dataclass(frozen=True)
class AnalysisClass:
    """A class of the analysis vocabulary and the ISO classes it groups (each a subclass of it)."""

    name: str
    label: str
    members: tuple[str, ...]
    comment: str


@dataclass(frozen=True)
class AnalysisProperty:
    """A property the derived layer writes (or the vocabulary graph carries)."""

    name: str
    kind: str  # "object" or "data"
    domain: str | None  # an sga: class name, or None
    comment: str


ANALYSIS_CLASSES: tuple[AnalysisClass, ...] = (
    AnalysisClass(
        "RoughingOperation", "roughing operation",
        ("facing_rough", "grooving_rough", "contouring_rough", "threading_rough",
         "bottom_and_side_rough_milling", "plane_rough_milling", "side_rough_milling"),
        "An operation that removes the bulk of the material and leaves an allowance for a later finishing "
        "operation. ISO 14649-11 and -12 name such operations *_rough but give them no common class."),
    AnalysisClass(
        "FinishingOperation", "finishing operation",
        ("facing_finish", "grooving_finish", "contouring_finish", "threading_finish",
         "bottom_and_side_finish_milling", "plane_finish_milling", "side_finish_milling"),
        "An operation that brings a surface to its final size and finish, usually after a roughing "
        "operation on the same feature. ISO 14649-11 and -12 name such operations *_finish."),
    AnalysisClass(
        "ThreadCuttingOperation", "thread cutting operation",
        ("threading", "tapping", "thread_drilling"),
        "An operation that cuts a thread: turned (ISO 14649-12 threading) or in a hole (ISO 14649-11 "
        "tapping, thread drilling)."),
    AnalysisClass(
        "ThreadCuttingTool", "thread cutting tool",
        ("turning_threading_tool", "milling_threading_tool", "thread_mill", "tap"),
        "A tool body that cuts threads, whether a turning insert, a thread mill or a tap; ISO 14649-111 "
        "and -121 declare them in different branches of the tool hierarchy."),
    AnalysisClass(
        "ExecutionStep", "execution step", (),
        "One place in a program's flattened execution order (derived layer): the workingstep it executes, "
        "its 1-based order, the innermost workplan and the setup in force. A workingstep used twice has two "
        "steps."),
    AnalysisClass(
        "ClassCount", "class count", (),
        "How many instances of one class a loaded file holds (derived layer): the program, the class and the "
        "count, written at load so that a profile of the program need not read every instance."),
)

ANALYSIS_PROPERTIES: tuple[AnalysisProperty, ...] = (
    AnalysisProperty("order", "data", "ExecutionStep",
                     "1-based place of the step in the file's execution order: the project's main workplan "
                     "(or each top-level workplan) flattened depth first, nested workplans and other program "
                     "structures expanded where they stand."),
    AnalysisProperty("executes", "object", "ExecutionStep", "The workingstep executed at this step."),
    AnalysisProperty("workplan", "object", "ExecutionStep",
                     "The innermost workplan (or other program structure) that lists the workingstep."),
    AnalysisProperty("setup", "object", "ExecutionStep",
                     "The setup in force: that of the nearest enclosing workplan which names one "
                     "(ISO 14649-10 gives setups to workplans, not to workingsteps)."),
    AnalysisProperty("next", "object", "ExecutionStep", "The step executed right after this one."),
    AnalysisProperty("tool", "object", "ExecutionStep",
                     "The machining tool of the step's operation (absent for steps without one, such as a "
                     "rapid movement)."),
    AnalysisProperty("toolBefore", "object", "ExecutionStep",
                     "The tool of the nearest earlier step that has one: the tool in the spindle when this step "
                     "starts. A step whose sga:tool differs from it is a tool change."),
    AnalysisProperty("program", "object", "ExecutionStep",
                     "The loaded file's graph (the program) the step belongs to: the graph of the workingstep it "
                     "executes, stated on the step so that a query reads it in one scan."),
    AnalysisProperty("workingstepId", "data", "ExecutionStep",
                     "The Part 21 #id (p21:id) of the workingstep the step executes."),
    AnalysisProperty("operationId", "data", "ExecutionStep",
                     "The Part 21 #id (p21:id) of the operation of the workingstep the step executes."),
    AnalysisProperty("operationClass", "object", "ExecutionStep",
                     "The class of the operation of the workingstep the step executes, as the program's graph "
                     "types it (its own entity, not the superclasses the derived layer adds)."),
    AnalysisProperty("operation", "object", "ExecutionStep",
                     "The operation (its_operation) of the workingstep the step executes."),
    AnalysisProperty("workingstepName", "data", "ExecutionStep",
                     "The its_id of the workingstep the step executes (the data graph's value, copied so that "
                     "a query reads it in one scan of the steps)."),
    AnalysisProperty("operationName", "data", "ExecutionStep",
                     "The its_id of the operation of the workingstep the step executes."),
    AnalysisProperty("workplanName", "data", "ExecutionStep", "The its_id of the step's sga:workplan."),
    AnalysisProperty("setupName", "data", "ExecutionStep", "The its_id of the step's sga:setup."),
    AnalysisProperty("toolName", "data", "ExecutionStep", "The its_id of the step's sga:tool."),
    AnalysisProperty("toolId", "data", "ExecutionStep", "The Part 21 #id (p21:id) of the step's sga:tool."),
    AnalysisProperty("toolBodyClass", "object", "ExecutionStep",
                     "The class of the tool body of the step's sga:tool, as the program's graph types it (its "
                     "own entity, not the superclasses the derived layer adds)."),
    AnalysisProperty("operationType", "data", "ExecutionStep",
                     "The local name of the step's sga:operationClass (contouring_rough for "
                     "stepnc:contouring_rough), a string: what a row shows as the operation's type."),
    AnalysisProperty("toolBodyType", "data", "ExecutionStep",
                     "The local name of the step's sga:toolBodyClass, a string: what a row shows as the tool "
                     "body's type."),
    AnalysisProperty("typeName", "data", None,
                     "On a manufacturing feature or an operation: the local name of the class "
                     "the program's graph types it with (its own entity), a string: what a row shows as its type."),
    AnalysisProperty("featureId", "data", None,
                     "On a manufacturing feature: its Part 21 #id (p21:id), in the derived layer so that a "
                     "query reads the features' #ids in one scan instead of looking each one up."),
    AnalysisProperty("featureClass", "object", None,
                     "On a manufacturing feature: its class as the program's graph types it (its own entity, not "
                     "the superclasses the derived layer adds)."),
    AnalysisProperty("featureProgram", "object", None,
                     "On a manufacturing feature: the loaded file's graph (the program) it belongs to."),
    AnalysisProperty("countedIn", "object", "ClassCount", "The loaded file's graph whose instances are counted."),
    AnalysisProperty("countedClass", "object", "ClassCount", "The class a class count counts the instances of."),
    AnalysisProperty("instanceCount", "data", "ClassCount",
                     "How many instances the file's graph types with the counted class (named instances, not "
                     "typed values; instances of its subclasses not counted)."),
    AnalysisProperty("feature", "object", None,
                     "A manufacturing feature a workingstep machines: its_feature of a machining_workingstep, "
                     "each member of its_features of a turning_workingstep."),
    AnalysisProperty("index", "data", None,
                     "1-based position of an rdf:List cell in its list (derived for the lists of ISO 14649 "
                     "process attributes, not for geometry)."),
    AnalysisProperty("layerOf", "object", None, "The loaded file's graph a derived layer belongs to."),
    AnalysisProperty("layerVersion", "data", None,
                     "The format of a derived layer: the version of what stepnc-graph derives (queries warn about "
                     "a layer of another version: load the file again)."),
    AnalysisProperty("vocabularyDigest", "data", None,
                     "SHA-256 of the ontology files the vocabulary graph was loaded from; the loader rewrites "
                     "the graph when it differs from the shipped files."),
)

#: Own-words definitions of the core process entities (the ISO 14649-10 clause
#: that introduces each is cited, not quoted). Used by the HTML reference and
#: ``ontology/analysis.ttl`` (as ``skos:definition``).
CORE_DEFINITIONS: dict[str, str] = {
    "project": "The top of a program: names the main workplan to execute and the workpieces it makes "
               "(ISO 14649-10, project data).",
    "executable": "Anything a machine controller can execute: a workingstep, an NC function or a program "
                  "structure; its_id names it in the program.",
    "workplan": "An ordered list of executables run one after the other; nested workplans give a program "
                "its structure, and a workplan may name the setup its elements run in.",
    "program_structure": "An executable that arranges other executables: workplans in sequence, parallel "
                         "branches, alternatives, conditions and loops.",
    "workingstep": "One machining step of the program: one operation applied to one feature, with the "
                   "security plane the tool retracts to.",
    "machining_workingstep": "A workingstep that machines a single manufacturing feature with a single "
                             "machining operation.",
    "turning_workingstep": "A turning workingstep that machines several features with one operation "
                           "(ISO 14649-12).",
    "setup": "How the workpiece is clamped and placed on the machine: its origin, security plane and "
             "workpiece placements. Workplans name the setup their steps run in.",
    "workpiece": "The part being made, with its material and, optionally, its finished and raw shapes.",
    "manufacturing_feature": "A region of the workpiece to machine (a face, a diameter, a groove, a "
                             "hole...), described by its shape, not by tool motion; its_operations lists "
                             "the operations that machine it.",
    "machining_operation": "What is done to a feature: the tool, the technology (feed and speed), machine "
                           "functions and strategy, independent of any tool path.",
    "machining_tool": "The tool an operation uses, identified by its_id; a cutting tool's body says what "
                      "kind of tool it is (turning, grooving, drill...).",
    "cutting_tool": "A tool with a tool body (its kind and dimensions) and cutting components.",
    "tool_body": "The kind of a cutting tool and its dimensions: general turning tool, grooving tool, "
                 "drill, end mill, ...",
    "technology": "Feed rate and the speed settings of an operation (turning: constant spindle speed or "
                  "constant cutting speed with a maximum).",
    "machine_functions": "Coolant, chip removal and other machine functions switched for an operation.",
    "turning_machining_strategy": "How a turning operation moves through the material: passes, cutting "
                                  "depth, directions (ISO 14649-12).",
    "nc_function": "An executable that is not machining: a stop, a message, a tool or pallet change.",
}


#: ISO 14649 entities that are geometry or bookkeeping in all but name: explicit
#: toolpaths (a cutter-location polyline per operation), tolerances and free
#: parameters, with their subtypes. In real programs they are as numerous as
#: the instances process questions are about, and no such question needs them
#: generically, so the derived layer leaves them out (see derive.py).
NOT_DERIVED = ("toolpath", "toolpath_list", "toleranced_length_measure", "plus_minus_value", "limits_and_fits",
               "property_parameter")


def derived_entities(model: SchemaModel) -> frozenset[str]:
    """Entities whose instances get a derived layer (closure, generic values, labels, list positions).

    Those of the ISO 14649 schemas -- not the ISO 10303 resources (points,
    directions, curves, ...) and not :data:`NOT_DERIVED`.
    """
    left_out = {n for root in NOT_DERIVED for n in (root, *model.all_subtypes(root))}
    return frozenset(e.name for e in model.entities.values()
                     if model.schemas[e.schema].status != "resource" and e.name not in left_out)
