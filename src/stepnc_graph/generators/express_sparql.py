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
from collections.abc import Callable
from dataclasses import dataclass, field
from decimal import Decimal
from typing import Any

import express_schema.parse as ast

from stepnc_graph.core.naming import P21_NS, Naming
from stepnc_graph.schema.model import (
    AggregateType,
    Attribute,
    BaseType,
    Entity,
    EnumerationType,
    NamedType,
    SimpleType,
    TypeRef,
)
from stepnc_graph.schema.view import SchemaModel
from stepnc_graph.vocabulary.typemap import value_shape

RDF_NS = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
UNKNOWN = "?unknown"
#: the largest SIZEOF count compared by enumerating distinct members
MAX_COUNT = 4


class Untranslatable(Exception):
    """A rule (or part of one) with no exact SHACL rendering; the message says why."""


# -- EXPRESS text of a tree ---------------------------------------------------------------

_OPS = {
    ast.BinaryOp.ADD: "+", ast.BinaryOp.SUBTRACT: "-", ast.BinaryOp.MULTIPLY: "*",
    ast.BinaryOp.REAL_DIVIDE: "/", ast.BinaryOp.INTEGER_DIVIDE: "DIV", ast.BinaryOp.MODULO: "MOD",
    ast.BinaryOp.POWER: "**", ast.BinaryOp.OR: "OR", ast.BinaryOp.XOR: "XOR", ast.BinaryOp.AND: "AND",
    ast.BinaryOp.CONCAT: "||", ast.BinaryOp.LESS_THAN: "<", ast.BinaryOp.GREATER_THAN: ">",
    ast.BinaryOp.LESS_EQUAL: "<=", ast.BinaryOp.GREATER_EQUAL: ">=", ast.BinaryOp.EQUAL: "=",
    ast.BinaryOp.NOT_EQUAL: "<>", ast.BinaryOp.INSTANCE_EQUAL: ":=:", ast.BinaryOp.INSTANCE_NOT_EQUAL: ":<>:",
    ast.BinaryOp.IN: "IN", ast.BinaryOp.LIKE: "LIKE",
}


def express_text(e: Any) -> str:
    """The expression written back as EXPRESS (fully parenthesised binary operations).

    The model's ``WhereRule.source`` is cut from the file at the expression
    node, which loses an opening parenthesis when the rule starts with one; the
    tree has the whole rule.
    """
    if isinstance(e, ast.BinaryExpr):
        return f"({express_text(e.left)} {_OPS[e.op]} {express_text(e.right)})"
    if isinstance(e, ast.UnaryExpr):
        op = {ast.UnaryOp.NOT: "NOT ", ast.UnaryOp.NEG: "-", ast.UnaryOp.PLUS: "+"}[e.op]
        return f"{op}{express_text(e.operand)}"
    if isinstance(e, ast.Call):
        return f"{express_text(e.callee)}({', '.join(express_text(a.value) for a in e.args)})"
    if isinstance(e, ast.NameRef):
        return str(e.identifier)
    if isinstance(e, ast.Self):
        return "SELF"
    if isinstance(e, ast.AttributeRef):
        return f"{express_text(e.source)}.{e.identifier}"
    if isinstance(e, ast.QualifiedAttributeRef):
        return f"{express_text(e.source)}\\{e.group_qualifier}.{e.attribute}"
    if isinstance(e, ast.IndexExpr):
        return f"{express_text(e.source)}[{express_text(e.index)}]"
    if isinstance(e, ast.QueryExpr):
        return f"QUERY({e.variable} <* {express_text(e.aggregate)} | {express_text(e.predicate)})"
    if isinstance(e, ast.Interval):
        lo = "<" if e.left_to_center is ast.BinaryOp.LESS_THAN else "<="
        hi = "<" if e.center_to_right is ast.BinaryOp.LESS_THAN else "<="
        return f"{{{express_text(e.left)} {lo} {express_text(e.center)} {hi} {express_text(e.right)}}}"
    if isinstance(e, ast.AggregateLiteral):
        return "[" + ", ".join(express_text(x.expr) for x in e.elements) + "]"
    if isinstance(e, ast.StringLiteral):
        return "'" + str(e.value).replace("'", "''") + "'"
    if isinstance(e, ast.LogicalLiteral):
        return str(e.value.name)
    if isinstance(e, ast.IndeterminateLiteral):
        return "?"
    if isinstance(e, (ast.IntegerLiteral, ast.RealLiteral)):
        return str(e.value)
    return f"<{type(e).__name__}>"


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
_FLIP = {ast.BinaryOp.GREATER_THAN: ast.BinaryOp.LESS_THAN, ast.BinaryOp.LESS_THAN: ast.BinaryOp.GREATER_THAN,
         ast.BinaryOp.GREATER_EQUAL: ast.BinaryOp.LESS_EQUAL, ast.BinaryOp.LESS_EQUAL: ast.BinaryOp.GREATER_EQUAL}


def _number(e: Any) -> Decimal | int | None:
    if isinstance(e, ast.IntegerLiteral):
        return int(e.value)
    if isinstance(e, ast.RealLiteral):
        return Decimal(e.value)
    if isinstance(e, ast.UnaryExpr) and e.op is ast.UnaryOp.NEG:
        inner = _number(e.operand)
        return -inner if inner is not None else None
    return None


def defined_type_facets(expr: Any) -> list[tuple[str, Decimal | int]]:
    """``SELF > 0`` or ``{1 <= SELF <= 31}`` as SHACL value-range facets.

    A defined type's value is never indeterminate where the rule applies (the
    rule constrains values that are there), so the facets are exact.
    """
    if isinstance(expr, ast.Interval) and isinstance(expr.center, ast.Self):
        lo, hi = _number(expr.left), _number(expr.right)
        if lo is None or hi is None:
            raise Untranslatable("an interval bound is not a literal number")
        return [("minExclusive" if expr.left_to_center is ast.BinaryOp.LESS_THAN else "minInclusive", lo),
                ("maxExclusive" if expr.center_to_right is ast.BinaryOp.LESS_THAN else "maxInclusive", hi)]
    if isinstance(expr, ast.BinaryExpr) and expr.op in _FACET_OF:
        if isinstance(expr.left, ast.Self) and _number(expr.right) is not None:
            return [(_FACET_OF[expr.op], _number(expr.right))]  # type: ignore[list-item]
        if isinstance(expr.right, ast.Self) and _number(expr.left) is not None:
            return [(_FACET_OF[_FLIP[expr.op]], _number(expr.left))]  # type: ignore[list-item]
    if isinstance(expr, ast.BinaryExpr) and expr.op is ast.BinaryOp.AND:
        return defined_type_facets(expr.left) + defined_type_facets(expr.right)
    raise Untranslatable("only comparisons of SELF with literal numbers become value ranges")


# -- the SPARQL compiler ---------------------------------------------------------------------------


@dataclass
class _Scope:
    """One group graph pattern being built: bindings first, then OPTIONALs, then FILTERs."""

    bindings: list[str] = field(default_factory=list)
    optionals: list[str] = field(default_factory=list)
    known: dict[tuple[str, tuple[str, ...]], str] = field(default_factory=dict)  # path -> its variable

    def text(self, filters: list[str]) -> str:
        return " ".join(self.bindings + self.optionals + [f"FILTER({f})" for f in filters])


@dataclass
class _Path:
    """An instance or simple value reached from an always-bound variable along single-valued steps."""

    root: str
    steps: tuple[str, ...]  # SPARQL path elements
    type: TypeRef | None
    always: bool = False  # bound whenever the root is (no steps)


@dataclass
class _Agg:
    """An aggregate: how to enumerate its members, and whether it is determinate."""

    members: Callable[["_Compiler", str, str], str]  # (compiler, member var, cell var) -> pattern
    element: TypeRef
    is_list: bool
    present: str  # SPARQL boolean: the aggregate has a value (else SIZEOF etc. are UNKNOWN)
    head: _Path | None = None  # a LIST attribute: the path to its first cell (for indexing)


@dataclass
class _Scalar:
    expr: str
    type: TypeRef | None


_Value = _Path | _Agg | _Scalar


class _Compiler:
    """Compiles one rule of one entity; raises Untranslatable on the first construct it cannot render."""

    def __init__(self, model: SchemaModel, naming: Naming, entity: Entity) -> None:
        self.model = model
        self.n = naming
        self.entity = entity
        self.counter = itertools.count(1)
        self.scope = _Scope()
        self.vars: dict[str, tuple[str, TypeRef]] = {}  # query variable -> (SPARQL var, element type)
        self.self_members: set[str] = set()  # SPARQL vars ranging over an aggregate attribute of SELF
        self.notes: list[str] = []
        #: SET index variables: members pattern -> (the SET, index -> variable)
        self.set_indexed: dict[str, tuple[_Agg, dict[int, str]]] = {}
        self.set_hits = 0
        self.last_comparison_strict = False

    def fresh(self, stem: str = "v") -> str:
        return f"?{stem}{next(self.counter)}"

    # -- attributes -------------------------------------------------------------------------

    def iri(self, a: Attribute) -> str:
        return f"<{self.n.attribute(a.entity, a.name)}>"

    def attribute(self, source: TypeRef | None, name: str, group: str | None = None) -> Attribute:
        """The attribute ``name`` of a value of type ``source`` (a SELECT: all members must agree)."""
        if group is not None:
            candidates = [group]
        else:
            if not isinstance(source, NamedType):
                raise Untranslatable(f"attribute {name} of a value that is not an entity")
            decl = self.model.get(source.name)
            if isinstance(decl, Entity):
                candidates = [decl.name]
            elif self.model.select_behind(source.name) is not None:
                candidates = [m for m in self.model.select_closure(source.name) if m in self.model.entities]
            else:
                raise Untranslatable(f"attribute {name} of a value of type {source.name}")
        found = {a for c in candidates if (a := self.model.attribute(c, name)) is not None}
        if not found:
            # EXPRESS resolves an attribute of a SELECT value on the instance at
            # hand: one of a subtype's, indeterminate for instances without it
            found = {a for c in candidates for sub in self.model.all_subtypes(c)
                     if (a := self.model.attribute(sub, name)) is not None}
        if len(found) != 1:
            raise Untranslatable(f"attribute {name} does not denote one attribute of {', '.join(candidates)}")
        return found.pop()

    def step(self, base: _Path, a: Attribute) -> _Value:
        """``base.a``: a longer path for single values, an aggregate for SETs and LISTs."""
        if a.kind == "derived":
            if (a.entity, a.name) == ("geometric_representation_item", "dim"):
                return self.dimension(base)
            raise Untranslatable(f"uses the derived attribute {a.entity}.{a.name} := {a.expression}")
        if a.kind == "inverse":
            raise Untranslatable(f"uses the inverse attribute {a.entity}.{a.name}")
        shape = value_shape(self.model, self.n, a.type)
        p = self.iri(a)
        if shape.form in ("literal", "node"):
            return _Path(base.root, base.steps + (p,), a.type)
        agg = self.model.base_type(a.type)
        assert isinstance(agg, AggregateType)
        prefix = base.steps
        root = base.root
        if shape.form == "repeated":
            def set_members(c: _Compiler, m: str, cell: str) -> str:
                return f"{root} {'/'.join(prefix + (p,))} {m} ."
            owner = self.fresh("o")
            head = f"{root} {'/'.join(prefix)} {owner} ." if prefix else ""
            subject = owner if prefix else root
            present = (f"EXISTS {{ {head} {{ {subject} {p} ?any }} UNION "
                       f"{{ {subject} <{P21_NS}emptyAggregate> {p} }} }}")
            return _Agg(set_members, agg.element, False, present)

        def list_members(c: _Compiler, m: str, cell: str) -> str:
            return f"{root} {'/'.join(prefix + (p,))}/<{RDF_NS}rest>* {cell} . {cell} <{RDF_NS}first> {m} ."
        return _Agg(list_members, agg.element, True, f"EXISTS {{ {root} {'/'.join(prefix + (p,))} ?any }}",
                    _Path(root, prefix + (p,), a.type))

    def dimension(self, base: _Path) -> _Scalar:
        """``dim`` of a geometric_representation_item (ISO 10303-42 dimension_of).

        In the shipped resource schemas ``dimension_of(item)`` is the
        ``coordinate_space_dimension`` of the context of ``x[1]``, ``x`` being
        ``using_representations(item)``: the representations whose items
        reference ``item`` directly or through a chain of representation_items
        and founded_items (ISO 10303-43 using_items). It is indeterminate (the
        rule is satisfied) when no representation uses the item. ``x`` is a SET
        whose order nothing fixes; ISO 10303-43's rule compatible_dimension makes
        all its contexts agree, and the query checks each of them.
        """
        # The item is reached inside the OPTIONAL, from an always-bound root (an
        # item variable bound by an earlier OPTIONAL could be unbound here and
        # would then match anything). The representations' (item, dim) pairs are
        # an uncorrelated sub-SELECT: evaluated once, not walked up from every item. It returns
        # $this (SHACL 5.3.1 requires every sub-SELECT to) without using it: unbound inside, it
        # joins with every focus node, which is what substituting the focus node would give.
        item = self.fresh("item")
        reach = (f"{base.root} {'/'.join(base.steps)} {item} ." if base.steps
                 else f"FILTER(sameTerm({item}, {base.root}))")
        dim = self.fresh("dim")
        rep, top, ctx = self.fresh("rep"), self.fresh("top"), self.fresh("ctx")
        items = f"<{self.n.attribute('representation', 'items')}>"
        context = f"<{self.n.attribute('representation', 'context_of_items')}>"
        csd = f"<{self.n.attribute('geometric_representation_context', 'coordinate_space_dimension')}>"
        chain = self.using_chain(top, item)
        pairs = (f"{{ SELECT DISTINCT $this {item} {dim} WHERE {{ {rep} {items} {top} . {chain} {rep} {context} {ctx} . "
                 f"{ctx} {csd} {dim} }} }}")
        self.scope.optionals.append(f"OPTIONAL {{ {pairs} {reach} }}" if not base.steps
                                    else f"OPTIONAL {{ {reach} {pairs} }}")
        self.notes.append("dim: the coordinate_space_dimension of every representation using the item")
        return _Scalar(dim, SimpleType(BaseType.INTEGER))

    def using_chain(self, top: str, item: str) -> str:
        """A pattern: ``item`` is ``top`` or is used by it through representation items.

        The nodes of the chain must be representation_items or founded_items. A
        property path cannot test the type of the nodes it passes, so the path
        takes the attributes declared by those entities whose value can be such
        an item. An attribute of another entity that some subtype that *is* a
        representation item inherits (``region.feature_placement``, inherited by
        ``topological_region``) needs that test: the pattern takes it once,
        with its subject's type checked. That is exact when no chain can pass
        two such attributes, which is checked on the schema.
        """
        users = {e for e in self.model.entities
                 if self.model.is_subtype(e, "representation_item") or self.model.is_subtype(e, "founded_item")}
        plain: list[str] = []
        mixed: dict[str, list[str]] = {}  # property -> subtypes of its entity that are items
        for e in sorted(self.model.entities):
            for a in self.model.entity(e).explicit:
                if not self.may_hold(a.type, users):
                    continue
                if e in users:
                    plain.append(self.iri(a))
                elif any(s in users for s in self.model.all_subtypes(e)):
                    mixed[self.iri(a)] = [s for s in self.model.all_subtypes(e) if s in users]
        members = f"(<{RDF_NS}rest>*/<{RDF_NS}first>)*"
        step = f"(({'|'.join(plain)})/{members})*"
        if not mixed:
            return f"{top} {step} {item} ."
        self.check_single_mixed(mixed)
        z, t, y = self.fresh("z"), self.fresh("t"), self.fresh("y")
        branches = []
        for prop, subjects in sorted(mixed.items()):
            classes = ", ".join(f"<{self.n.declaration(c)}>" for c in subjects)
            branches.append(f"{{ {top} {step} {z} . {z} a {t} . FILTER({t} IN ({classes})) "
                            f"{z} {prop}/{members} {y} . {y} {step} {item} }}")
        return f"{{ {top} {step} {item} }} UNION " + " UNION ".join(branches) + " "

    def check_single_mixed(self, mixed: dict[str, list[str]]) -> None:
        """No chain passes two of the ``mixed`` attributes: their values cannot lead back to one."""
        owners = {self.model.attribute(s, iri.rsplit(".", 1)[1][:-1]) for iri, subs in mixed.items() for s in subs}
        subjects = {a.entity for a in owners if a is not None}
        for iri, subs in mixed.items():
            a = self.model.attribute(subs[0], iri.rsplit(".", 1)[1][:-1])
            assert a is not None
            reached = self.reachable(a.type)
            if any(self.model.is_subtype(r, s) or self.model.is_subtype(s, r) for r in reached for s in subjects):
                raise Untranslatable(f"dim: a chain of representation items may pass {a.entity}.{a.name} twice")

    def reachable(self, t: TypeRef) -> set[str]:
        """Entities a value of type ``t`` can lead to through explicit attributes (type level)."""
        seen: set[str] = set()
        stack = [t]
        while stack:
            base = self.model.base_type(stack.pop())
            while isinstance(base, AggregateType):
                base = self.model.base_type(base.element)
            if not isinstance(base, NamedType):
                continue
            names = self.model.select_closure(base.name) if self.model.select_behind(base.name) else (base.name,)
            for n in names:
                if n not in self.model.entities:
                    continue
                for e in (n, *self.model.all_subtypes(n)):
                    if e not in seen:
                        seen.add(e)
                        stack.extend(a.type for a in self.model.all_attributes(e) if a.kind == "explicit")
        return seen

    def may_hold(self, t: TypeRef, users: set[str]) -> bool:
        """Whether a value of type ``t`` (through aggregates and SELECTs) can be one of ``users``."""
        base = self.model.base_type(t)
        while isinstance(base, AggregateType):
            base = self.model.base_type(base.element)
        if not isinstance(base, NamedType):
            return False
        names = self.model.select_closure(base.name) if self.model.select_behind(base.name) else (base.name,)
        return any(n in self.model.entities and (n in users or any(s in users for s in self.model.all_subtypes(n)))
                   for n in names)

    def materialize(self, v: _Value) -> str:
        """A SPARQL variable (or term) holding the value; unbound when it is indeterminate."""
        if isinstance(v, _Scalar):
            return v.expr
        if isinstance(v, _Agg):
            raise Untranslatable("an aggregate where a single value is expected")
        if not v.steps:
            return v.root
        key = (v.root, v.steps)
        if key not in self.scope.known:
            var = self.fresh()
            self.scope.optionals.append(f"OPTIONAL {{ {v.root} {'/'.join(v.steps)} {var} }}")
            self.scope.known[key] = var
        return self.scope.known[key]

    # -- expressions ------------------------------------------------------------------------

    def value(self, e: Any) -> _Value:
        if isinstance(e, ast.Self):
            return _Path("$this", (), NamedType(self.entity.name), always=True)
        if isinstance(e, ast.NameRef):
            name = str(e.identifier).lower()
            if name in self.vars:
                var, t = self.vars[name]
                return _Path(var, (), t, always=True)
            return self.step(_Path("$this", (), NamedType(self.entity.name), always=True),
                             self.attribute(NamedType(self.entity.name), name))
        if isinstance(e, (ast.AttributeRef, ast.QualifiedAttributeRef)):
            base = self.value(e.source)
            if not isinstance(base, _Path):
                raise Untranslatable("attribute of a computed value")
            if isinstance(e, ast.AttributeRef):
                a = self.attribute(base.type, str(e.identifier).lower())
            else:
                a = self.attribute(base.type, str(e.attribute).lower(), str(e.group_qualifier).lower())
            return self.step(base, a)
        if isinstance(e, ast.IndexExpr):
            return self.index(e)
        if isinstance(e, ast.QueryExpr):
            return self.query(e)
        if isinstance(e, (ast.IntegerLiteral, ast.RealLiteral)) or (
                isinstance(e, ast.UnaryExpr) and e.op is ast.UnaryOp.NEG and _number(e) is not None):
            n = _number(e)
            return _Scalar(str(n) if isinstance(n, int) else f"{n}e0", None)
        if isinstance(e, ast.StringLiteral):
            return _Scalar('"' + str(e.value).replace("\\", "\\\\").replace('"', '\\"') + '"', None)
        if isinstance(e, ast.BinaryExpr) and e.op in (ast.BinaryOp.ADD, ast.BinaryOp.SUBTRACT,
                                                       ast.BinaryOp.MULTIPLY, ast.BinaryOp.REAL_DIVIDE):
            if isinstance(e.left, ast.AggregateLiteral) or isinstance(e.right, ast.AggregateLiteral):
                raise Untranslatable("an aggregate literal in arithmetic (set intersection with TYPEOF)")
            left, right = self.scalar(e.left), self.scalar(e.right)
            return _Scalar(f"({left} {_OPS[e.op]} {right})", None)
        if isinstance(e, ast.Call) and self.callee(e) == "sizeof":
            raise Untranslatable("SIZEOF compared with something other than a literal integer")
        return _Scalar(self.boolean(e), None)

    def scalar(self, e: Any) -> str:
        return self.materialize(self.value(e))

    def callee(self, e: ast.Call) -> str:
        return str(e.callee.identifier).lower() if isinstance(e.callee, ast.NameRef) else ""

    def index(self, e: ast.IndexExpr) -> _Value:
        base = self.value(e.source)
        i = _number(e.index)
        if not isinstance(base, _Agg) or not isinstance(i, int) or i < 1:
            raise Untranslatable("an index that is not a literal position in an aggregate attribute")
        if not base.is_list:
            return self.set_member(base, i)
        if base.head is None:
            raise Untranslatable("indexes a computed aggregate")
        # the i-th member is rdf:first of the cell reached by i-1 rdf:rest steps
        steps = base.head.steps + (f"<{RDF_NS}rest>",) * (i - 1) + (f"<{RDF_NS}first>",)
        return _Path(base.head.root, steps, base.element)

    def set_member(self, agg: _Agg, i: int) -> _Path:
        """``s[i]`` of a SET: a variable ranging over its members, distinct per index.

        A SET has no order (the Part 21 order is not kept, and EXPRESS fixes
        none), so ``s[1]`` may be any member. The rule is then reported only
        when it is FALSE for every order: see :func:`translate_rule`.
        """
        key = agg.members(self, "?M", "?C")
        slots = self.set_indexed.setdefault(key, (agg, {}))[1]
        if i not in slots:
            slots[i] = self.fresh("s")
        self.set_hits += 1
        return _Path(slots[i], (), agg.element, always=True)

    def query(self, e: ast.QueryExpr) -> _Agg:
        source = self.value(e.aggregate)
        if not isinstance(source, _Agg):
            raise Untranslatable("QUERY over a value that is not an aggregate attribute")
        name = str(e.variable).lower()
        predicate = e.predicate
        of_self = self.is_self_aggregate(e.aggregate)

        def members(c: _Compiler, m: str, cell: str) -> str:
            inner = source.members(c, m, cell)
            saved_scope, saved_vars = c.scope, dict(c.vars)
            c.scope = _Scope([inner])
            c.vars[name] = (m, source.element)
            if of_self:
                c.self_members.add(m)
            try:
                cond = c.boolean(predicate)
                return c.scope.text([cond])
            finally:
                c.scope, c.vars = saved_scope, saved_vars
        return _Agg(members, source.element, source.is_list, source.present)

    def is_self_aggregate(self, e: Any) -> bool:
        """``SELF.attr`` or ``attr`` (an attribute of SELF itself)."""
        if isinstance(e, ast.NameRef):
            return str(e.identifier).lower() not in self.vars
        return isinstance(e, ast.AttributeRef) and isinstance(e.source, ast.Self)

    # -- logical expressions -------------------------------------------------------------

    def boolean(self, e: Any) -> str:
        if isinstance(e, ast.BinaryExpr):
            if e.op in (ast.BinaryOp.AND, ast.BinaryOp.OR):
                op = "&&" if e.op is ast.BinaryOp.AND else "||"
                return f"({self.boolean(e.left)} {op} {self.boolean(e.right)})"
            if e.op is ast.BinaryOp.XOR:
                return f"({self.boolean(e.left)} != {self.boolean(e.right)})"
            if e.op is ast.BinaryOp.IN:
                return self.membership(e)
            if e.op in (ast.BinaryOp.INSTANCE_EQUAL, ast.BinaryOp.INSTANCE_NOT_EQUAL):
                left, right = self.scalar(e.left), self.scalar(e.right)
                same = f"IF(bound({left}) && bound({right}), sameTerm({left}, {right}), {UNKNOWN})"
                return same if e.op is ast.BinaryOp.INSTANCE_EQUAL else f"!{same}"
            if e.op in (ast.BinaryOp.EQUAL, ast.BinaryOp.NOT_EQUAL, ast.BinaryOp.LESS_THAN, ast.BinaryOp.GREATER_THAN,
                        ast.BinaryOp.LESS_EQUAL, ast.BinaryOp.GREATER_EQUAL):
                return self.comparison(e)
            raise Untranslatable(f"operator {_OPS.get(e.op, e.op)} in a logical position")
        if isinstance(e, ast.UnaryExpr) and e.op is ast.UnaryOp.NOT:
            return f"!{self.boolean(e.operand)}"
        if isinstance(e, ast.Call):
            fn = self.callee(e)
            if fn == "exists":
                return self.exists(e.args[0].value)
            raise Untranslatable(f"calls the function {fn.upper() or express_text(e.callee)}")
        if isinstance(e, ast.Interval):
            lo, hi = _number(e.left), _number(e.right)
            if lo is None or hi is None:
                raise Untranslatable("an interval bound is not a literal number")
            x = self.scalar(e.center)
            op1 = "<" if e.left_to_center is ast.BinaryOp.LESS_THAN else "<="
            op2 = "<" if e.center_to_right is ast.BinaryOp.LESS_THAN else "<="
            return f"({lo} {op1} {x} && {x} {op2} {hi})"
        if isinstance(e, ast.LogicalLiteral):
            return {"TRUE": "true", "FALSE": "false"}.get(e.value.name, UNKNOWN)
        v = self.value(e) if isinstance(e, (ast.NameRef, ast.AttributeRef, ast.QualifiedAttributeRef)) else None
        if isinstance(v, _Path) and isinstance(self.model.base_type(v.type) if v.type else None, SimpleType):
            base = self.model.base_type(v.type)  # type: ignore[arg-type]
            assert isinstance(base, SimpleType)
            if base.base.value == "BOOLEAN":
                var = self.materialize(v)
                return f"(datatype({var}) = <http://www.w3.org/2001/XMLSchema#boolean> && {var})"
        raise Untranslatable(f"{express_text(e)} is not a logical expression stepnc-graph can render")

    def exists(self, e: Any) -> str:
        v = self.value(e)
        if isinstance(v, _Agg):
            return v.present
        if isinstance(v, _Path) and v.always:
            return "true"
        return f"bound({self.materialize(v)})"

    def membership(self, e: ast.BinaryExpr) -> str:
        """``'SCHEMA.ENTITY' IN TYPEOF(x)``: x is an instance of that entity or a subtype."""
        right = e.right
        if not (isinstance(right, ast.Call) and self.callee(right) == "typeof" and isinstance(e.left, ast.StringLiteral)):
            raise Untranslatable("IN other than 'SCHEMA.ENTITY' IN TYPEOF(x)")
        name = str(e.left.value).split(".")[-1].lower()
        if name not in self.model.entities:
            raise Untranslatable(f"TYPEOF test for {name}, which is not an entity")
        operand = self.value(right.args[0].value)
        if isinstance(operand, _Agg):
            # TYPEOF of an aggregate value names no entity: the test is FALSE
            # whenever the aggregate is there, UNKNOWN when it is not
            self.notes.append("TYPEOF of an aggregate holds no entity name: the IN test is FALSE when it is set")
            return f"IF({operand.present}, false, {UNKNOWN})"
        x = self.materialize(operand)
        classes = ", ".join(f"<{self.n.declaration(c)}>" for c in (name, *self.model.all_subtypes(name)))
        t = self.fresh("t")
        test = f"EXISTS {{ {x} a {t} . FILTER({t} IN ({classes})) }}"
        return test if x.startswith("$") or x in self.bound_vars() else f"IF(bound({x}), {test}, {UNKNOWN})"

    def bound_vars(self) -> set[str]:
        return {var for var, _ in self.vars.values()}

    def comparison(self, e: ast.BinaryExpr) -> str:
        for side, other in ((e.left, e.right), (e.right, e.left)):
            if isinstance(side, ast.Call) and self.callee(side) == "sizeof":
                n = _number(other)
                if not isinstance(n, int):
                    raise Untranslatable("SIZEOF compared with something other than a literal integer")
                op = e.op if side is e.left else _FLIP.get(e.op, e.op)
                return self.size_test(side.args[0].value, op, n)
        if self.is_enum_name(e.left) or self.is_enum_name(e.right):
            name, other = (e.left, e.right) if self.is_enum_name(e.left) else (e.right, e.left)
            item, value = self.enum_operand(name, self.value(other)), self.materialize(self.value(other))
            a, b = (item, value) if name is e.left else (value, item)
        else:
            hits = self.set_hits
            left = self.value(e.left)
            middle = self.set_hits
            right = self.value(e.right)
            self.last_comparison_strict = middle > hits and self.set_hits > middle
            if self.is_entity(left) or self.is_entity(right):
                return self.entity_equality(e, left, right)
            a, b = self.materialize(left), self.materialize(right)
        symbol = {ast.BinaryOp.EQUAL: "=", ast.BinaryOp.NOT_EQUAL: "!="}.get(e.op, _OPS[e.op])
        return f"({a} {symbol} {b})"

    def is_entity(self, v: _Value) -> bool:
        t = v.type if isinstance(v, _Path) else None
        if not isinstance(t, NamedType):
            return False
        return t.name in self.model.entities or any(
            m in self.model.entities for m in self.model.select_closure(t.name))

    def entity_equality(self, e: ast.BinaryExpr, left: _Value, right: _Value) -> str:
        """``it = SELF`` with ``it`` a member of an aggregate attribute of SELF.

        EXPRESS ``=`` on entity instances compares their values recursively
        (ISO 10303-11 12.2.1.7). A member of SELF's own attribute is one step
        closer to the leaves than SELF, so on acyclic data it can equal SELF
        only by being SELF; on a cycle through SELF the recursive comparison has
        no end and instance identity is the only answer it can give.
        """
        if e.op not in (ast.BinaryOp.EQUAL, ast.BinaryOp.NOT_EQUAL):
            raise Untranslatable("ordering comparison of entity instances")
        sides = {self.materialize(left), self.materialize(right)}
        if "$this" not in sides or not (sides - {"$this"}) <= self.self_members:
            raise Untranslatable("value comparison (=) of entity instances other than SELF with a member of "
                                 "one of its own aggregates")
        other = (sides - {"$this"}).pop()
        self.notes.append("= of SELF with a member of its own aggregate: instance identity (see the docs)")
        return f"sameTerm({other}, $this)" if e.op is ast.BinaryOp.EQUAL else f"!sameTerm({other}, $this)"

    def is_enum_name(self, e: Any) -> bool:
        """A bare name that is neither a variable nor an attribute of SELF: an enumeration item."""
        if not isinstance(e, ast.NameRef):
            return False
        name = str(e.identifier).lower()
        return name not in self.vars and self.model.attribute(self.entity.name, name) is None

    def enum_operand(self, e: Any, other: _Value) -> str:
        """A bare name compared with an enumeration value: that enumeration's item."""
        name = str(e.identifier).lower()
        if not isinstance(other, _Path) or not isinstance(other.type, NamedType):
            raise Untranslatable(f"{name} compared with a value that is not of an enumeration type")
        decl = self.model.get(other.type.name)
        _, base = self.model.underlying_chain(other.type.name)
        if isinstance(base, NamedType):
            decl = self.model.get(base.name)
        if isinstance(decl, EnumerationType) and name in decl.items:
            return f"<{self.n.enum_item(decl.name, name)}>"
        raise Untranslatable(f"{name} is neither an attribute nor an item of {other.type.name}")

    def at_least(self, agg: _Agg, k: int, n: int | None = None) -> str:
        """The aggregate has ``k`` or more members (list cells, for a LIST).

        Written as an OPTIONAL binding a witness, tested with ``bound``, not as
        ``EXISTS``: the same truth value, and stores (Oxigraph among them) join
        an OPTIONAL with the focus node already bound, while they may evaluate
        an EXISTS over a property path for every node of the graph.
        """
        if k <= 0:
            return "true"
        if k > MAX_COUNT:
            raise Untranslatable(f"SIZEOF compared with {n if n is not None else k}: more than {MAX_COUNT} "
                                 "members to tell apart")
        names = [(self.fresh("m"), self.fresh("c")) for _ in range(k)]
        parts = [agg.members(self, m, c) for m, c in names]
        keys = [c if agg.is_list else m for m, c in names]
        distinct = [f"!sameTerm({a}, {b})" for a, b in itertools.combinations(keys, 2)]
        body = " ".join(f"{{ {p} }}" for p in parts) + (f" FILTER({' && '.join(distinct)})" if distinct else "")
        self.scope.optionals.append(f"OPTIONAL {{ {body} }}")
        return f"bound({names[0][0]})"

    def size_test(self, agg_expr: Any, op: Any, n: int) -> str:
        agg = self.value(agg_expr)
        if not isinstance(agg, _Agg):
            raise Untranslatable("SIZEOF of something that is not an aggregate attribute or QUERY")

        def at_least(k: int) -> str:
            return self.at_least(agg, k, n)

        tests = {
            ast.BinaryOp.EQUAL: lambda: f"({at_least(n)} && !{at_least(n + 1)})",
            ast.BinaryOp.NOT_EQUAL: lambda: f"!({at_least(n)} && !{at_least(n + 1)})",
            ast.BinaryOp.GREATER_THAN: lambda: at_least(n + 1),
            ast.BinaryOp.GREATER_EQUAL: lambda: at_least(n),
            ast.BinaryOp.LESS_THAN: lambda: f"!{at_least(n)}",
            ast.BinaryOp.LESS_EQUAL: lambda: f"!{at_least(n + 1)}",
        }
        if op not in tests:
            raise Untranslatable("SIZEOF with an operator other than a comparison")
        test = tests[op]()
        return test if agg.present == "true" else f"IF({agg.present}, {test}, {UNKNOWN})"


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
    if own(cmp.left) == target and _number(cmp.right) is not None:
        return CoreCheck(target, _FACET_OF[cmp.op], _number(cmp.right))  # type: ignore[arg-type]
    if own(cmp.right) == target and _number(cmp.left) is not None:
        return CoreCheck(target, _FACET_OF[_FLIP[cmp.op]], _number(cmp.left))  # type: ignore[arg-type]
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


def _aggregate_typeof(c: "_Compiler", e: Any) -> "_Agg | None":
    """The aggregate ``x`` of ``'S.E' IN TYPEOF(x)``, when ``e`` is such a test on an aggregate."""
    if not (isinstance(e, ast.BinaryExpr) and e.op is ast.BinaryOp.IN and isinstance(e.left, ast.StringLiteral)
            and isinstance(e.right, ast.Call) and c.callee(e.right) == "typeof"):
        return None
    try:
        operand = c.value(e.right.args[0].value)
    except Untranslatable:
        return None
    return operand if isinstance(operand, _Agg) else None


def _possible(c: "_Compiler", e: Any) -> frozenset[str]:
    """The truth values (ISO 10303-11 three-valued logic) ``e`` can take over all instances, as far
    as its form shows: ``'S.E' IN TYPEOF(aggregate)`` is FALSE (TYPEOF of an aggregate names no
    entity), UNKNOWN too when the aggregate may be unset; every other test may be anything."""
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
    return frozenset({_T, _F, _U})


def _mandatory(c: "_Compiler", e: Any) -> bool:
    """Whether ``e`` names a mandatory attribute of the rule's entity: set in every instance that is
    otherwise valid (a missing one is reported by its own shape, sh:minCount)."""
    if not isinstance(e, ast.NameRef):
        return False
    a = c.model.attribute(c.entity.name, str(e.identifier).lower())
    return a is not None and a.kind == "explicit" and not a.optional


def never_satisfied(model: SchemaModel, naming: Naming, entity: Entity, expr: Any) -> str | None:
    """Why no instance of ``entity`` can satisfy the rule ``expr`` (it is FALSE whatever the data),
    or None when some instance may: a defect of the schema, not of any program."""
    c = _Compiler(model, naming, entity)
    if _possible(c, expr) != frozenset({_F}):
        return None
    return ("as written it is FALSE for every instance: 'S.E' IN TYPEOF(x) of an aggregate x is FALSE "
            "(TYPEOF of an aggregate names no entity), and the rule admits nothing else")


def _disjuncts(e: Any) -> list[Any]:
    if isinstance(e, ast.BinaryExpr) and e.op is ast.BinaryOp.OR:
        return _disjuncts(e.left) + _disjuncts(e.right)
    return [e]


def _intent(model: SchemaModel, naming: Naming, entity: Entity, expr: Any) -> Translation | None:
    """The evident intent of a rule that ORs ``'S.E' IN TYPEOF(x)`` tests on one aggregate ``x``:
    each member of ``x`` is one of those entities (or a subtype). None for any other form."""
    c = _Compiler(model, naming, entity)
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


def translate_rule(model: SchemaModel, naming: Naming, entity: Entity, expr: Any) -> Translation:
    """The SHACL rendering of one entity WHERE rule; raises :class:`Untranslatable`.

    A rule no instance can satisfy (:func:`never_satisfied`) is a defect of the schema: its
    evident intent is checked instead where its form shows one (:func:`_intent`), and it is not
    checked otherwise -- a correct program is never non-conforming for the schema's mistake."""
    defect = never_satisfied(model, naming, entity, expr)
    if defect is not None:
        intent = _intent(model, naming, entity, expr)
        if intent is None:
            raise Untranslatable(f"schema defect: {defect}; no evident intent to check instead")
        return dataclasses.replace(intent, defect=defect)
    core = _core(model, entity, expr)
    if core is not None:
        return Translation(core=core)
    c = _Compiler(model, naming, entity)
    condition = c.boolean(expr)
    notes = "; ".join(dict.fromkeys(c.notes)) or None
    if c.set_indexed:
        return Translation(sparql=_all_orders(c, expr, condition), note=notes)
    body = c.scope.text([f"!{condition}" if condition.startswith("(") else f"!({condition})"])
    query = f"SELECT DISTINCT $this WHERE {{ {body} }}"
    return Translation(sparql=query, note=notes)


def _all_orders(c: _Compiler, expr: Any, condition: str) -> str:
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
        sizes.append(c.at_least(agg, max(slots)))
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
