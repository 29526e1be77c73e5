"""SHACL constraint components, one class each: its SPARQL forms, its default message, its clause.

A component turns one *use* (a shape and the values of its parameters) into:

* :meth:`Component.violations` -- SELECT queries run once over the data graph,
  one row (``?this``, maybe ``?value``, ``?path``) per validation result, with
  the focus nodes bound by the pattern the compiler gives (its targets);
* :meth:`Component.holds` -- a SPARQL boolean expression "focus node ``v``
  meets this use", for shapes nested in ``sh:node``, ``sh:not``, ``sh:and``,
  ``sh:or``, ``sh:xone`` and ``sh:qualifiedValueShape``;
* optionally :meth:`Component.witnesses` -- graph patterns, one per way ``v``
  can fail, which Oxigraph joins with the outer binding (a ``NOT EXISTS`` over
  a property path it evaluates without it: quadratic); None where only the
  boolean form exists.

The compiler (:mod:`.engine`) keeps targets, paths, nesting and the dispatch
over :data:`REGISTRY`; adding a component is adding a class to the module of
its family and an instance to :data:`REGISTRY`. Clauses are those of the W3C
SHACL Recommendation (2017).

Value nodes are the focus node itself for a node shape and the nodes its path
reaches for a property shape (SHACL 2.3.2); most components test each value
node on its own (:class:`ValueComponent`).

The families, one module each: :mod:`.value_type`, :mod:`.cardinality`, :mod:`.value_range`
(value range and string-based), :mod:`.property_pair`, :mod:`.logical`, :mod:`.shape_based`,
:mod:`.other_constraints` and :mod:`.sparql_based`; their base is :mod:`.component_base`.
"""

from __future__ import annotations

from stepnc_graph.validation.component_base import (
    Compiling,
    Component,
    TRUE,
    Use,
    ValueComponent,
    Violation,
    XSD,
    local,
)
from stepnc_graph.validation.cardinality import MaxCountComponent, MinCountComponent
from stepnc_graph.validation.logical import AndComponent, NotComponent, OrComponent, XoneComponent
from stepnc_graph.validation.other_constraints import ClosedComponent, HasValueComponent, InComponent
from stepnc_graph.validation.property_pair import (
    DisjointComponent,
    EqualsComponent,
    LessThanComponent,
    LessThanOrEqualsComponent,
)
from stepnc_graph.validation.shape_based import (
    NodeComponent,
    PropertyComponent,
    QualifiedMaxCountComponent,
    QualifiedMinCountComponent,
)
from stepnc_graph.validation.sparql_based import SparqlComponent, custom_components
from stepnc_graph.validation.value_range import (
    LanguageInComponent,
    MaxExclusiveComponent,
    MaxInclusiveComponent,
    MaxLengthComponent,
    MinExclusiveComponent,
    MinInclusiveComponent,
    MinLengthComponent,
    PatternComponent,
    UniqueLangComponent,
)
from stepnc_graph.validation.value_type import ClassComponent, DatatypeComponent, NodeKindComponent

__all__ = ["Compiling", "Component", "NON_VALIDATING", "PARAMETERS", "PropertyComponent", "REGISTRY", "TRUE", "Use", "ValueComponent", "Violation", "XSD", "custom_components", "local"]

#: the built-in components, in the order their checks are compiled
REGISTRY: tuple[Component, ...] = (
    ClassComponent(), DatatypeComponent(), NodeKindComponent(), InComponent(), HasValueComponent(),
    MinInclusiveComponent(), MaxInclusiveComponent(), MinExclusiveComponent(), MaxExclusiveComponent(),
    MinLengthComponent(), MaxLengthComponent(), PatternComponent(), LanguageInComponent(), NodeComponent(),
    NotComponent(), AndComponent(), OrComponent(), XoneComponent(), MinCountComponent(), MaxCountComponent(),
    UniqueLangComponent(), EqualsComponent(), DisjointComponent(), LessThanComponent(),
    LessThanOrEqualsComponent(), QualifiedMinCountComponent(), QualifiedMaxCountComponent(), ClosedComponent(),
    SparqlComponent(), PropertyComponent(),
)

#: sh: parameters of the built-in components
PARAMETERS = frozenset(p for comp in REGISTRY for p in (comp.key, *comp.others) if p)
#: sh: terms a shape may carry that constrain nothing (targets, path, annotations, severity ...)
NON_VALIDATING = frozenset({
    "targetClass", "targetNode", "targetSubjectsOf", "targetObjectsOf", "path", "severity", "message",
    "deactivated", "name", "description", "order", "group", "defaultValue", "prefixes", "declare", "select",
    "ask", "prefix", "namespace", "labelTemplate", "parameter", "validator", "nodeValidator",
    "propertyValidator", "optional", "resultAnnotation", "intersection", "detail",
})


