"""The vocabulary graph every store holds, and the analysis terms stepnc-graph adds.

SPARQL engines do not read ontologies they are not given: ``?c
rdfs:subClassOf* stepnc:turning_machine_tool_body`` finds nothing unless the
subclass axioms are in the store. So the loader keeps the whole generated
vocabulary (``ontology/*.ttl``: the ISO classes, attribute properties and
enumeration items, the ``p21:`` terms, the generic ``attr:`` properties and
the ``sga:`` analysis terms) in one named graph, :data:`VOCABULARY_GRAPH`,
with the SHA-256 of those files recorded in it (``sga:vocabularyDigest``).
A load rewrites the graph when it is missing or its digest differs from the
shipped files, inside the same atomic load as the file. Exports of one file
never include it (the writer reads the file's graph only).

The analysis vocabulary (:data:`ANALYSIS_CLASSES`, :data:`ANALYSIS_PROPERTIES`)
names what ISO 14649 leaves implicit: it has ``facing_rough`` and
``contouring_rough`` but no class of roughing operations; it orders
workingsteps only through nested ``LIST``s. These definitions are the single
source for ``ontology/analysis.ttl`` (generated) and for the derived layer
(:mod:`stepnc_graph.loading.derive`).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import lru_cache
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import pyoxigraph as ox

from stepnc_graph.core.naming import ANALYSIS_NS, VOCABULARY_GRAPH
from stepnc_graph.core.resources import ontology_dir

if TYPE_CHECKING:
    from stepnc_graph.schema.view import SchemaModel
    from stepnc_graph.store import Store

DIGEST = ANALYSIS_NS + "vocabularyDigest"


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


def vocabulary_files(directory: Path | None = None) -> tuple[Path, ...]:
    """The Turtle files the vocabulary graph holds: every ``ontology/*.ttl``, sorted."""
    return tuple(sorted((directory or ontology_dir()).glob("*.ttl")))


def digest(files: tuple[Path, ...]) -> str:
    """SHA-256 over the files' names and bytes (a change to any file makes the graph stale)."""
    h = hashlib.sha256()
    for path in files:
        h.update(path.name.encode("utf-8") + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


@lru_cache(maxsize=4)
def _digest(files: tuple[Path, ...], stamps: tuple[float, ...]) -> str:
    del stamps  # part of the cache key only: a rewritten file is read again
    return digest(files)


def vocabulary_digest(directory: Path | None = None) -> str:
    """The digest of the shipped ontology files (cached per file state)."""
    files = vocabulary_files(directory)
    return _digest(files, tuple(p.stat().st_mtime for p in files))


def stored_digest(store: Store) -> str | None:
    """The digest recorded in the store's vocabulary graph; None if there is no such graph."""
    rows = store.query(f"SELECT ?d WHERE {{ GRAPH <{VOCABULARY_GRAPH}> {{ <{VOCABULARY_GRAPH}> <{DIGEST}> ?d }} }}")
    for row in rows:
        return row[0].value if isinstance(row[0], ox.Literal) else None
    return None


def vocabulary_status(store: Store, directory: Path | None = None) -> str:
    """``current``, ``stale`` (written from other ontology files) or ``missing``."""
    found = stored_digest(store)
    if found is None:
        return "missing"
    return "current" if found == vocabulary_digest(directory) else "stale"


def ensure_vocabulary(store: Store, directory: Path | None = None,
                      target: Callable[[str], str] | None = None) -> bool:
    """Write the vocabulary graph when it is missing or stale; True if it was written.

    Called by the loader inside a file's atomic load (``before_commit``), so
    on disk the rewrite is covered by the load's checkpoint; ``target`` (the load's) names the
    graph to write instead, which a remote store stages and swaps in with the program.
    """
    value = vocabulary_digest(directory)
    if stored_digest(store) == value:
        return False
    where = target(VOCABULARY_GRAPH) if target is not None else VOCABULARY_GRAPH
    store.update(f"DROP SILENT GRAPH <{where}>")
    store.add_turtle(where, vocabulary_turtle(directory))
    return True


def vocabulary_turtle(directory: Path | None = None) -> str:
    """The vocabulary graph's content as one Turtle document: the ontology files one after the
    other (Turtle allows prefix declarations anywhere; the files use no blank node labels and no
    base, so nothing in one can change the meaning of another) and the digest.

    One text for the store to parse, rather than a Python object per triple: this is most of
    what a throw-away store pays before its first query.
    """
    texts = [path.read_text(encoding="utf-8") for path in vocabulary_files(directory)]
    digest_line = f"<{VOCABULARY_GRAPH}> <{DIGEST}> {ox.Literal(vocabulary_digest(directory))} .\n"
    return "\n".join([*texts, digest_line])


def vocabulary_for_queries(store: Store) -> None:
    """Give a throw-away (in-memory) store the vocabulary graph before queries read it: loads into
    such a store skip it, as most throw-away stores are never queried (load --memory, validate)."""
    if is_throwaway(store):
        ensure_vocabulary(store)


def is_throwaway(store: Store) -> bool:
    """An in-memory store: the loader leaves the vocabulary graph out of it (see above)."""
    from stepnc_graph.store import GraphStore

    return store.path is None and isinstance(store, GraphStore)


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
