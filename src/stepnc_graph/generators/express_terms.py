"""What the rule compiler (:mod:`.express_sparql`) is built on: :class:`Untranslatable`, the EXPRESS
text of a tree (for messages and notes), literal numbers, and the values an expression compiles to
(a path from an always-bound variable, an aggregate, a SPARQL scalar) in the group pattern being built.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from decimal import Decimal
from typing import TYPE_CHECKING, Any

import express_schema.parse as ast

from stepnc_graph.schema.model import TypeRef

if TYPE_CHECKING:
    from stepnc_graph.generators.express_compiler import RuleCompiler

RDF_NS = "http://www.w3.org/1999/02/22-rdf-syntax-ns#"
UNKNOWN = "?unknown"
#: the largest SIZEOF count compared by enumerating distinct members
MAX_COUNT = 4


class Untranslatable(Exception):
    """A rule (or part of one) with no exact SHACL rendering; the message says why."""


# -- EXPRESS text of a tree ---------------------------------------------------------------

OPS = {
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
        return f"({express_text(e.left)} {OPS[e.op]} {express_text(e.right)})"
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


FLIP = {ast.BinaryOp.GREATER_THAN: ast.BinaryOp.LESS_THAN, ast.BinaryOp.LESS_THAN: ast.BinaryOp.GREATER_THAN,
         ast.BinaryOp.GREATER_EQUAL: ast.BinaryOp.LESS_EQUAL, ast.BinaryOp.LESS_EQUAL: ast.BinaryOp.GREATER_EQUAL}


def literal_number(e: Any) -> Decimal | int | None:
    if isinstance(e, ast.IntegerLiteral):
        return int(e.value)
    if isinstance(e, ast.RealLiteral):
        return Decimal(e.value)
    if isinstance(e, ast.UnaryExpr) and e.op is ast.UnaryOp.NEG:
        inner = literal_number(e.operand)
        return -inner if inner is not None else None
    return None


# -- the SPARQL compiler ---------------------------------------------------------------------------


@dataclass
class Scope:
    """One group graph pattern being built: bindings first, then OPTIONALs, then FILTERs."""

    bindings: list[str] = field(default_factory=list)
    optionals: list[str] = field(default_factory=list)
    known: dict[tuple[str, tuple[str, ...]], str] = field(default_factory=dict)  # path -> its variable

    def text(self, filters: list[str]) -> str:
        return " ".join(self.bindings + self.optionals + [f"FILTER({f})" for f in filters])


@dataclass
class PathValue:
    """An instance or simple value reached from an always-bound variable along single-valued steps."""

    root: str
    steps: tuple[str, ...]  # SPARQL path elements
    type: TypeRef | None
    always: bool = False  # bound whenever the root is (no steps)


@dataclass
class Agg:
    """An aggregate: how to enumerate its members, and whether it is determinate."""

    members: Callable[["RuleCompiler", str, str], str]  # (compiler, member var, cell var) -> pattern
    element: TypeRef
    is_list: bool
    present: str  # SPARQL boolean: the aggregate has a value (else SIZEOF etc. are UNKNOWN)
    head: PathValue | None = None  # a LIST attribute: the path to its first cell (for indexing)


@dataclass
class Scalar:
    expr: str
    type: TypeRef | None


Value = PathValue | Agg | Scalar


