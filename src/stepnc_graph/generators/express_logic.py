"""The logical expressions of a domain rule, compiled to SPARQL in ISO 10303-11's three-valued logic
(:mod:`.express_sparql`): AND, OR, XOR and NOT, comparisons, TYPEOF membership, EXISTS, intervals and
SIZEOF tests; an indeterminate operand is an unbound variable, which SPARQL's logic reads as UNKNOWN.
"""

from __future__ import annotations

import itertools
from typing import TYPE_CHECKING, Any

import express_schema.parse as ast

from stepnc_graph.schema.model import EnumerationType, NamedType, SimpleType
from stepnc_graph.generators.express_terms import (MAX_COUNT, UNKNOWN, Untranslatable, Agg, FLIP, literal_number, OPS,
                                                 PathValue, Value, express_text)

if TYPE_CHECKING:
    from stepnc_graph.generators.express_compiler import RuleCompiler


class Conditions:
    """The logical expressions of the rule that ``c`` compiles (the values they test come from ``c``)."""

    def __init__(self, c: RuleCompiler) -> None:
        self.c = c

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
                left, right = self.c.scalar(e.left), self.c.scalar(e.right)
                same = f"IF(bound({left}) && bound({right}), sameTerm({left}, {right}), {UNKNOWN})"
                return same if e.op is ast.BinaryOp.INSTANCE_EQUAL else f"!{same}"
            if e.op in (ast.BinaryOp.EQUAL, ast.BinaryOp.NOT_EQUAL, ast.BinaryOp.LESS_THAN, ast.BinaryOp.GREATER_THAN,
                        ast.BinaryOp.LESS_EQUAL, ast.BinaryOp.GREATER_EQUAL):
                return self.comparison(e)
            raise Untranslatable(f"operator {OPS.get(e.op, e.op)} in a logical position")
        if isinstance(e, ast.UnaryExpr) and e.op is ast.UnaryOp.NOT:
            return f"!{self.boolean(e.operand)}"
        if isinstance(e, ast.Call):
            fn = self.c.callee(e)
            if fn == "exists":
                return self.exists(e.args[0].value)
            raise Untranslatable(f"calls the function {fn.upper() or express_text(e.callee)}")
        if isinstance(e, ast.Interval):
            lo, hi = literal_number(e.left), literal_number(e.right)
            if lo is None or hi is None:
                raise Untranslatable("an interval bound is not a literal number")
            x = self.c.scalar(e.center)
            op1 = "<" if e.left_to_center is ast.BinaryOp.LESS_THAN else "<="
            op2 = "<" if e.center_to_right is ast.BinaryOp.LESS_THAN else "<="
            return f"({lo} {op1} {x} && {x} {op2} {hi})"
        if isinstance(e, ast.LogicalLiteral):
            return {"TRUE": "true", "FALSE": "false"}.get(e.value.name, UNKNOWN)
        v = self.c.value(e) if isinstance(e, (ast.NameRef, ast.AttributeRef, ast.QualifiedAttributeRef)) else None
        if isinstance(v, PathValue) and isinstance(self.c.model.base_type(v.type) if v.type else None, SimpleType):
            base = self.c.model.base_type(v.type)  # type: ignore[arg-type]
            assert isinstance(base, SimpleType)
            if base.base.value == "BOOLEAN":
                var = self.c.materialize(v)
                return f"(datatype({var}) = <http://www.w3.org/2001/XMLSchema#boolean> && {var})"
        raise Untranslatable(f"{express_text(e)} is not a logical expression stepnc-graph can render")

    def exists(self, e: Any) -> str:
        v = self.c.value(e)
        if isinstance(v, Agg):
            return v.present
        if isinstance(v, PathValue) and v.always:
            return "true"
        return f"bound({self.c.materialize(v)})"

    def membership(self, e: ast.BinaryExpr) -> str:
        """``'SCHEMA.ENTITY' IN TYPEOF(x)``: x is an instance of that entity or a subtype."""
        right = e.right
        if not (isinstance(right, ast.Call) and self.c.callee(right) == "typeof" and isinstance(e.left, ast.StringLiteral)):
            raise Untranslatable("IN other than 'SCHEMA.ENTITY' IN TYPEOF(x)")
        name = str(e.left.value).split(".")[-1].lower()
        if name not in self.c.model.entities:
            raise Untranslatable(f"TYPEOF test for {name}, which is not an entity")
        operand = self.c.value(right.args[0].value)
        if isinstance(operand, Agg):
            # TYPEOF of an aggregate value names no entity: the test is FALSE
            # whenever the aggregate is there, UNKNOWN when it is not
            self.c.notes.append("TYPEOF of an aggregate holds no entity name: the IN test is FALSE when it is set")
            return f"IF({operand.present}, false, {UNKNOWN})"
        x = self.c.materialize(operand)
        classes = ", ".join(f"<{self.c.n.declaration(c)}>" for c in (name, *self.c.model.all_subtypes(name)))
        t = self.c.fresh("t")
        test = f"EXISTS {{ {x} a {t} . FILTER({t} IN ({classes})) }}"
        return test if x.startswith("$") or x in self.bound_vars() else f"IF(bound({x}), {test}, {UNKNOWN})"

    def bound_vars(self) -> set[str]:
        return {var for var, _ in self.c.vars.values()}

    def comparison(self, e: ast.BinaryExpr) -> str:
        for side, other in ((e.left, e.right), (e.right, e.left)):
            if isinstance(side, ast.Call) and self.c.callee(side) == "sizeof":
                n = literal_number(other)
                if not isinstance(n, int):
                    raise Untranslatable("SIZEOF compared with something other than a literal integer")
                op = e.op if side is e.left else FLIP.get(e.op, e.op)
                return self.size_test(side.args[0].value, op, n)
        if self.is_enum_name(e.left) or self.is_enum_name(e.right):
            name, other = (e.left, e.right) if self.is_enum_name(e.left) else (e.right, e.left)
            item, value = self.enum_operand(name, self.c.value(other)), self.c.materialize(self.c.value(other))
            a, b = (item, value) if name is e.left else (value, item)
        else:
            hits = self.c.set_hits
            left = self.c.value(e.left)
            middle = self.c.set_hits
            right = self.c.value(e.right)
            self.c.last_comparison_strict = middle > hits and self.c.set_hits > middle
            if self.is_entity(left) or self.is_entity(right):
                return self.entity_equality(e, left, right)
            a, b = self.c.materialize(left), self.c.materialize(right)
        symbol = {ast.BinaryOp.EQUAL: "=", ast.BinaryOp.NOT_EQUAL: "!="}.get(e.op, OPS[e.op])
        return f"({a} {symbol} {b})"

    def is_entity(self, v: Value) -> bool:
        t = v.type if isinstance(v, PathValue) else None
        if not isinstance(t, NamedType):
            return False
        return t.name in self.c.model.entities or any(
            m in self.c.model.entities for m in self.c.model.select_closure(t.name))

    def entity_equality(self, e: ast.BinaryExpr, left: Value, right: Value) -> str:
        """``it = SELF`` with ``it`` a member of an aggregate attribute of SELF.

        EXPRESS ``=`` on entity instances compares their values recursively
        (ISO 10303-11 12.2.1.7). A member of SELF's own attribute is one step
        closer to the leaves than SELF, so on acyclic data it can equal SELF
        only by being SELF; on a cycle through SELF the recursive comparison has
        no end and instance identity is the only answer it can give.
        """
        if e.op not in (ast.BinaryOp.EQUAL, ast.BinaryOp.NOT_EQUAL):
            raise Untranslatable("ordering comparison of entity instances")
        sides = {self.c.materialize(left), self.c.materialize(right)}
        if "$this" not in sides or not (sides - {"$this"}) <= self.c.self_members:
            raise Untranslatable("value comparison (=) of entity instances other than SELF with a member of "
                                 "one of its own aggregates")
        other = (sides - {"$this"}).pop()
        self.c.notes.append("= of SELF with a member of its own aggregate: instance identity (see the docs)")
        return f"sameTerm({other}, $this)" if e.op is ast.BinaryOp.EQUAL else f"!sameTerm({other}, $this)"

    def is_enum_name(self, e: Any) -> bool:
        """A bare name that is neither a variable nor an attribute of SELF: an enumeration item."""
        if not isinstance(e, ast.NameRef):
            return False
        name = str(e.identifier).lower()
        return name not in self.c.vars and self.c.model.attribute(self.c.entity.name, name) is None

    def enum_operand(self, e: Any, other: Value) -> str:
        """A bare name compared with an enumeration value: that enumeration's item."""
        name = str(e.identifier).lower()
        if not isinstance(other, PathValue) or not isinstance(other.type, NamedType):
            raise Untranslatable(f"{name} compared with a value that is not of an enumeration type")
        decl = self.c.model.get(other.type.name)
        _, base = self.c.model.underlying_chain(other.type.name)
        if isinstance(base, NamedType):
            decl = self.c.model.get(base.name)
        if isinstance(decl, EnumerationType) and name in decl.items:
            return f"<{self.c.n.enum_item(decl.name, name)}>"
        raise Untranslatable(f"{name} is neither an attribute nor an item of {other.type.name}")

    def at_least(self, agg: Agg, k: int, n: int | None = None) -> str:
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
        names = [(self.c.fresh("m"), self.c.fresh("c")) for _ in range(k)]
        parts = [agg.members(self.c, m, c) for m, c in names]
        keys = [c if agg.is_list else m for m, c in names]
        distinct = [f"!sameTerm({a}, {b})" for a, b in itertools.combinations(keys, 2)]
        body = " ".join(f"{{ {p} }}" for p in parts) + (f" FILTER({' && '.join(distinct)})" if distinct else "")
        self.c.scope.optionals.append(f"OPTIONAL {{ {body} }}")
        return f"bound({names[0][0]})"

    def size_test(self, agg_expr: Any, op: Any, n: int) -> str:
        agg = self.c.value(agg_expr)
        if not isinstance(agg, Agg):
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


