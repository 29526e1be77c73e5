"""EXPRESS domain rules (WHERE) -> SHACL: SHACL Core where the meaning is the same, else SPARQL.

Works on the parsed expression trees the schema model keeps in
``WhereRule.expr`` (express-schema syntax trees), never on rule text.

**Three-valued logic.** ISO 10303-11 evaluates domain rules in a logic with
UNKNOWN: a comparison with an indeterminate operand (an unset OPTIONAL
attribute, an index past the end of a list) is UNKNOWN, and a rule that is
UNKNOWN is satisfied. SPARQL's expression errors behave exactly like UNKNOWN
in its logical operators (``error || true`` is true, ``error && false`` is
false, ``!error`` is an error, and FILTER keeps only true). So an
indeterminate value is an unbound variable, and a rule's query keeps the
focus nodes for which ``!(rule)`` is true -- those where the rule is FALSE.
``?unknown`` below is a variable that is never bound: the literal UNKNOWN.

**Never mistranslate.** Anything whose meaning cannot be reproduced exactly
raises :class:`Untranslatable` with the reason; the generator lists those rules
(``stepnc-graph ontology stats``) instead of emitting an approximation.

The queries are portable SHACL-SPARQL (SHACL 5.3.1: no VALUES, no MINUS, and
every sub-SELECT returns ``$this``), so every conformant engine -- pySHACL, the
Rust engines, stepnc-graph's own -- runs the same text.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from decimal import Decimal
from typing import Any

import express_schema.parse as ast
from express_schema.lex import Identifier

from stepnc_graph.core.naming import Naming
from stepnc_graph.schema.model import Attribute, Entity, SimpleType
from stepnc_graph.schema.view import SchemaModel
from stepnc_graph.generators.express_compiler import RuleCompiler
from stepnc_graph.generators.express_terms import Untranslatable, Agg, FLIP, literal_number, express_text

__all__ = ["CoreCheck", "Translation", "Untranslatable", "defined_type_facets", "express_text", "never_satisfied",
           "translate_rule"]


# -- results ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CoreCheck:
    """A rule that is one SHACL Core property shape: ``path`` required, value ``facet`` ``value``."""

    attribute: Attribute
    facet: str  # minInclusive, minExclusive, maxInclusive, maxExclusive
    value: Decimal | int


@dataclass(frozen=True)
class Translation:
    """How a rule is checked: a Core property shape or a SPARQL SELECT of the failing ``$this``."""

    core: CoreCheck | None = None
    sparql: str | None = None
    note: str | None = None  # what an exact reading needed (documented in the shape)
    #: why no instance can satisfy the rule as written (a defect of the schema), when none can
    defect: str | None = None
    #: what is checked instead of such a rule: its evident intent, in words
    intent: str | None = None


# -- defined types: SELF compared with literals -> value ranges ------------------------------

_FACET_OF = {  # SELF op literal
    ast.BinaryOp.GREATER_THAN: "minExclusive", ast.BinaryOp.GREATER_EQUAL: "minInclusive",
    ast.BinaryOp.LESS_THAN: "maxExclusive", ast.BinaryOp.LESS_EQUAL: "maxInclusive",
}
def defined_type_facets(expr: Any) -> list[tuple[str, Decimal | int]]:
    """``SELF > 0`` or ``{1 <= SELF <= 31}`` as SHACL value-range facets.

    A defined type's value is never indeterminate where the rule applies (the
    rule constrains values that are there), so the facets are exact.
    """
    if isinstance(expr, ast.Interval) and isinstance(expr.center, ast.Self):
        lo, hi = literal_number(expr.left), literal_number(expr.right)
        if lo is None or hi is None:
            raise Untranslatable("an interval bound is not a literal number")
        return [("minExclusive" if expr.left_to_center is ast.BinaryOp.LESS_THAN else "minInclusive", lo),
                ("maxExclusive" if expr.center_to_right is ast.BinaryOp.LESS_THAN else "maxInclusive", hi)]
    if isinstance(expr, ast.BinaryExpr) and expr.op in _FACET_OF:
        if isinstance(expr.left, ast.Self) and literal_number(expr.right) is not None:
            return [(_FACET_OF[expr.op], literal_number(expr.right))]  # type: ignore[list-item]
        if isinstance(expr.right, ast.Self) and literal_number(expr.left) is not None:
            return [(_FACET_OF[FLIP[expr.op]], literal_number(expr.left))]  # type: ignore[list-item]
    if isinstance(expr, ast.BinaryExpr) and expr.op is ast.BinaryOp.AND:
        return defined_type_facets(expr.left) + defined_type_facets(expr.right)
    raise Untranslatable("only comparisons of SELF with literal numbers become value ranges")


def _core(model: SchemaModel, entity: Entity, expr: Any) -> CoreCheck | None:
    """``EXISTS(a) AND (a op literal)`` on one single-valued numeric attribute of SELF."""
    if not (isinstance(expr, ast.BinaryExpr) and expr.op is ast.BinaryOp.AND):
        return None
    ex, cmp = expr.left, expr.right
    if not (isinstance(ex, ast.Call) and isinstance(ex.callee, ast.NameRef)
            and str(ex.callee.identifier).lower() == "exists" and len(ex.args) == 1):
        return None
    if not (isinstance(cmp, ast.BinaryExpr) and cmp.op in _FACET_OF):
        return None

    def own(e: Any) -> Attribute | None:
        if isinstance(e, ast.AttributeRef) and isinstance(e.source, ast.Self):
            e = ast.NameRef(e.position, e.identifier)
        if not isinstance(e, ast.NameRef):
            return None
        a = model.attribute(entity.name, str(e.identifier).lower())
        if a is None or a.kind != "explicit":
            return None
        base = model.base_type(a.type)
        return a if isinstance(base, SimpleType) and base.base.value in ("REAL", "INTEGER", "NUMBER") else None

    target = own(ex.args[0].value)
    if target is None:
        return None
    if own(cmp.left) == target and literal_number(cmp.right) is not None:
        return CoreCheck(target, _FACET_OF[cmp.op], literal_number(cmp.right))  # type: ignore[arg-type]
    if own(cmp.right) == target and literal_number(cmp.left) is not None:
        return CoreCheck(target, _FACET_OF[FLIP[cmp.op]], literal_number(cmp.left))  # type: ignore[arg-type]
    return None


# -- rules no instance can satisfy -------------------------------------------------------------

_T, _F, _U = "T", "F", "U"
_NOT = {_T: _F, _F: _T, _U: _U}


def _and(a: str, b: str) -> str:
    return _F if _F in (a, b) else _U if _U in (a, b) else _T


def _or(a: str, b: str) -> str:
    return _T if _T in (a, b) else _U if _U in (a, b) else _F


def _xor(a: str, b: str) -> str:
    return _U if _U in (a, b) else _T if a != b else _F


def _aggregate_typeof(c: "RuleCompiler", e: Any) -> "Agg | None":
    """The aggregate ``x`` of ``'S.E' IN TYPEOF(x)``, when ``e`` is such a test on an aggregate."""
    if not (isinstance(e, ast.BinaryExpr) and e.op is ast.BinaryOp.IN and isinstance(e.left, ast.StringLiteral)
            and isinstance(e.right, ast.Call) and c.callee(e.right) == "typeof"):
        return None
    try:
        operand = c.value(e.right.args[0].value)
    except Untranslatable:
        return None
    return operand if isinstance(operand, Agg) else None


#: names TYPEOF gives besides those of the schemas' declared types: the simple and aggregation
#: types a value may have (ISO 10303-11, TYPEOF)
_BUILT_IN_TYPES = frozenset({"aggregate", "array", "bag", "binary", "boolean", "integer", "list", "logical",
                             "number", "real", "set", "string"})


def _undeclared_typeof(c: "RuleCompiler", e: Any) -> tuple[str, Any] | None:
    """(the name, the operand) of ``'S.X' IN TYPEOF(v)`` when X is no type the schemas declare
    nor a built-in one: TYPEOF gives only such names, so the test is never TRUE (the schema prefix
    and letter case set aside, as everywhere a TYPEOF string is read)."""
    if not (isinstance(e, ast.BinaryExpr) and e.op is ast.BinaryOp.IN and isinstance(e.left, ast.StringLiteral)
            and isinstance(e.right, ast.Call) and c.callee(e.right) == "typeof"):
        return None
    name = str(e.left.value).split(".")[-1].lower()
    if name in _BUILT_IN_TYPES or c.model.get(name) is not None:
        return None
    return name, e.right.args[0].value


def _possible(c: "RuleCompiler", e: Any) -> frozenset[str]:
    """The truth values (ISO 10303-11 three-valued logic) ``e`` can take over all instances, as far
    as its form shows: ``'S.E' IN TYPEOF(aggregate)`` is FALSE (TYPEOF of an aggregate names no
    entity), and so is ``'S.X' IN TYPEOF(v)`` for an X no schema declares; UNKNOWN too when the
    operand may be unset; every other test may be anything."""
    if isinstance(e, ast.UnaryExpr) and e.op is ast.UnaryOp.NOT:
        return frozenset(_NOT[v] for v in _possible(c, e.operand))
    if isinstance(e, ast.BinaryExpr) and e.op in (ast.BinaryOp.AND, ast.BinaryOp.OR, ast.BinaryOp.XOR):
        combine = {ast.BinaryOp.AND: _and, ast.BinaryOp.OR: _or, ast.BinaryOp.XOR: _xor}[e.op]
        left, right = _possible(c, e.left), _possible(c, e.right)
        return frozenset(combine(a, b) for a in left for b in right)
    agg = _aggregate_typeof(c, e)
    if agg is not None:
        always = agg.present == "true" or _mandatory(c, e.right.args[0].value)
        return frozenset({_F}) if always else frozenset({_F, _U})
    undeclared = _undeclared_typeof(c, e)
    if undeclared is not None:
        return frozenset({_F}) if _mandatory(c, undeclared[1]) else frozenset({_F, _U})
    return frozenset({_T, _F, _U})


def _mandatory(c: "RuleCompiler", e: Any) -> bool:
    """Whether ``e`` names a mandatory attribute of the rule's entity: set in every instance that is
    otherwise valid (a missing one is reported by its own shape, sh:minCount)."""
    if isinstance(e, ast.NameRef):
        name = str(e.identifier)
    elif isinstance(e, ast.AttributeRef) and isinstance(e.source, ast.Self):  # SELF.a
        name = str(e.identifier)
    elif isinstance(e, ast.QualifiedAttributeRef) and isinstance(e.source, ast.Self):  # SELF\supertype.a
        name = str(e.attribute)
    else:
        return False
    a = c.model.attribute(c.entity.name, name.lower())
    return a is not None and a.kind == "explicit" and not a.optional


def never_satisfied(model: SchemaModel, naming: Naming, entity: Entity, expr: Any) -> str | None:
    """Why no instance of ``entity`` can satisfy the rule ``expr`` (it is FALSE whatever the data),
    or None when some instance may: a defect of the schema, not of any program."""
    c = RuleCompiler(model, naming, entity)
    if _possible(c, expr) != frozenset({_F}):
        return None
    undeclared = sorted({u[0] for t in _tests(expr) if (u := _undeclared_typeof(c, t)) is not None
                         and _aggregate_typeof(c, t) is None})
    if undeclared:
        return (f"as written it is FALSE for every instance: TYPEOF gives only the names of types the schemas "
                f"declare (and built-in ones), {', '.join(repr(u) for u in undeclared)} names none of them, and "
                f"the rule admits nothing else")
    return ("as written it is FALSE for every instance: 'S.E' IN TYPEOF(x) of an aggregate x is FALSE "
            "(TYPEOF of an aggregate names no entity), and the rule admits nothing else")


def _tests(e: Any) -> list[Any]:
    """The operands of the NOT, AND, OR and XOR in ``e``, down to the tests they combine."""
    if isinstance(e, ast.UnaryExpr) and e.op is ast.UnaryOp.NOT:
        return _tests(e.operand)
    if isinstance(e, ast.BinaryExpr) and e.op in (ast.BinaryOp.AND, ast.BinaryOp.OR, ast.BinaryOp.XOR):
        return _tests(e.left) + _tests(e.right)
    return [e]


def _disjuncts(e: Any) -> list[Any]:
    if isinstance(e, ast.BinaryExpr) and e.op is ast.BinaryOp.OR:
        return _disjuncts(e.left) + _disjuncts(e.right)
    return [e]


def _intent(model: SchemaModel, naming: Naming, entity: Entity, expr: Any) -> Translation | None:
    """The evident intent of a rule that ORs ``'S.E' IN TYPEOF(x)`` tests on one aggregate ``x``:
    each member of ``x`` is one of those entities (or a subtype). None for any other form."""
    c = RuleCompiler(model, naming, entity)
    tests = _disjuncts(expr)
    aggs = [_aggregate_typeof(c, t) for t in tests]
    if any(a is None for a in aggs):
        return None  # _aggregate_typeof: each test is 'S.E' IN TYPEOF(x)
    operands = {express_text(t.right.args[0].value) for t in tests}
    if len(operands) != 1:
        return None
    names = [str(t.left.value).split(".")[-1].lower() for t in tests]
    if any(n not in model.entities for n in names):
        return None
    agg = aggs[0]
    assert agg is not None
    member, cell, t = c.fresh("m"), c.fresh("c"), c.fresh("t")
    classes = ", ".join(f"<{naming.declaration(n)}>" for n in dict.fromkeys(
        x for name in names for x in (name, *model.all_subtypes(name))))
    body = " ".join([agg.members(c, member, cell), *c.scope.optionals,
                     f"FILTER NOT EXISTS {{ {member} a {t} . FILTER({t} IN ({classes})) }}"])
    words = f"each member of {operands.pop()} is a {', '.join(names[:-1])} or {names[-1]}" if len(names) > 1 \
        else f"each member of {operands.pop()} is a {names[0]}"
    return Translation(sparql=f"SELECT DISTINCT $this WHERE {{ {body} }}", intent=words)


def _enumeration_intent(model: SchemaModel, naming: Naming, entity: Entity, expr: Any) -> Translation | None:
    """The evident intent of ``'S.X' IN TYPEOF(a)`` (ORed with itself, at most) where X is no type
    but an item of the enumeration that is ``a``'s type: ``a = X`` (TYPEOF of an enumeration value
    names its type, never an item). None for any other form."""
    c = RuleCompiler(model, naming, entity)
    found = {(u[0], express_text(u[1])) for t in _tests(expr) if (u := _undeclared_typeof(c, t)) is not None}
    tests = _disjuncts(expr)
    if len(found) != 1 or any(_undeclared_typeof(c, t) is None for t in tests):
        return None
    item = next(iter(found))[0]
    operand = tests[0].right.args[0].value
    equal = ast.BinaryExpr(tests[0].position, operand, ast.BinaryOp.EQUAL, ast.NameRef(tests[0].position, Identifier(item)))
    try:
        condition = c.logic.boolean(equal)
    except Untranslatable:
        return None  # X is no item of a's type: no evident intent
    body = c.scope.text([f"!{condition}" if condition.startswith("(") else f"!({condition})"])
    attribute = str(operand.identifier if isinstance(operand, ast.AttributeRef) else
                    operand.attribute if isinstance(operand, ast.QualifiedAttributeRef) else express_text(operand))
    return Translation(sparql=f"SELECT DISTINCT $this WHERE {{ {body} }}", intent=f"{attribute} is .{item.upper()}.")


def translate_rule(model: SchemaModel, naming: Naming, entity: Entity, expr: Any) -> Translation:
    """The SHACL rendering of one entity WHERE rule; raises :class:`Untranslatable`.

    A rule no instance can satisfy (:func:`never_satisfied`) is a defect of the schema: its
    evident intent is checked instead where its form shows one (:func:`_intent`), and it is not
    checked otherwise -- a correct program is never non-conforming for the schema's mistake."""
    defect = never_satisfied(model, naming, entity, expr)
    if defect is not None:
        intent = _intent(model, naming, entity, expr) or _enumeration_intent(model, naming, entity, expr)
        if intent is None:
            raise Untranslatable(f"schema defect: {defect}; no evident intent to check instead")
        return dataclasses.replace(intent, defect=defect)
    core = _core(model, entity, expr)
    if core is not None:
        return Translation(core=core)
    c = RuleCompiler(model, naming, entity)
    condition = c.logic.boolean(expr)
    notes = "; ".join(dict.fromkeys(c.notes)) or None
    if c.set_indexed:
        return Translation(sparql=_all_orders(c, expr, condition), note=notes)
    body = c.scope.text([f"!{condition}" if condition.startswith("(") else f"!({condition})"])
    query = f"SELECT DISTINCT $this WHERE {{ {body} }}"
    return Translation(sparql=query, note=notes)


def _all_orders(c: RuleCompiler, expr: Any, condition: str) -> str:
    """A rule that indexes a SET, reported when it is FALSE whatever order the SET is read in.

    Only a comparison whose two sides both use indexed members is accepted:
    it is UNKNOWN when an index is past the end, so the SET must have that
    many members; then every assignment of distinct members to the indices is
    one possible order, and the rule is FALSE for all orders when no
    assignment makes it TRUE or UNKNOWN.
    """
    if not (isinstance(expr, ast.BinaryExpr) and expr.op in _COMPARISONS and c.last_comparison_strict):
        raise Untranslatable("indexes a SET outside a comparison of two indexed members: which member is "
                             "first depends on an order neither RDF nor EXPRESS fixes")
    sizes, assignment = [], []
    for agg, slots in c.set_indexed.values():
        sizes.append(c.logic.at_least(agg, max(slots)))
        if agg.present != "true":
            sizes.append(agg.present)
        keys = []
        for var in slots.values():
            cell = c.fresh("c")
            assignment.append(f"{{ {agg.members(c, var, cell)} }}")
            keys.append(cell if agg.is_list else var)
        assignment += [f"FILTER(!sameTerm({a}, {b}))" for a, b in itertools.combinations(keys, 2)]
    body = " ".join(assignment + c.scope.optionals) + f" FILTER(COALESCE({condition}, true))"
    return (f"SELECT DISTINCT $this WHERE {{ FILTER({' && '.join(sizes)}) "
            f"FILTER NOT EXISTS {{ {body} }} }}")


_COMPARISONS = (ast.BinaryOp.EQUAL, ast.BinaryOp.NOT_EQUAL, ast.BinaryOp.LESS_THAN, ast.BinaryOp.GREATER_THAN,
                ast.BinaryOp.LESS_EQUAL, ast.BinaryOp.GREATER_EQUAL)
