"""Build the resolved :class:`SchemaModel` from EXPRESS syntax trees.

Resolution follows each schema's own scope: a type name used in schema S must
be declared in S or interfaced into S by REFERENCE FROM / USE FROM, possibly
through a chain of schemas (ISO 10303-11 11.4 allows re-interfacing). Names are
unique across the whole model, so a resolved name identifies one declaration.
All problems are collected and raised together as :class:`SchemaErrors`.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Literal

import express_schema.parse as ast

from stepnc_graph.express.comments import blank_comments, skip_string
from stepnc_graph.express.parser import ParsedSchema
from stepnc_graph.schema.errors import SchemaError, SchemaErrors
from stepnc_graph.schema.model import (
    AggregateKind,
    AggregateType,
    Attribute,
    BaseType,
    Declaration,
    DefinedType,
    Entity,
    EnumerationType,
    GenericType,
    Interface,
    NamedType,
    Redeclaration,
    SchemaInfo,
    SelectType,
    SimpleType,
    SourcePos,
    SupertypeExpr,
    SupertypeOperand,
    TypeRef,
    UniqueRule,
    WhereRule,
)
from stepnc_graph.schema.view import SchemaModel

_SIMPLE = {
    ast.BooleanType: BaseType.BOOLEAN,
    ast.IntegerType: BaseType.INTEGER,
    ast.LogicalType: BaseType.LOGICAL,
    ast.NumberType: BaseType.NUMBER,
    ast.RealType: BaseType.REAL,
    ast.StringType: BaseType.STRING,
    ast.BinaryType: BaseType.BINARY,
}


def _statement_text(clean: str, offset: int) -> str:
    """The text from ``offset`` to the next ``;`` outside strings, whitespace folded."""
    i, n = offset, len(clean)
    while i < n and clean[i] != ";":
        i = skip_string(clean, i) if clean[i] in "'\"" else i + 1
    return " ".join(clean[offset:i].split())


class _FileText:
    """Maps AST positions of one file to offsets and source snippets."""

    def __init__(self, parsed: ParsedSchema) -> None:
        self.file = parsed.filename
        self.clean = blank_comments(parsed.source)
        self._starts = [0]
        for k, ch in enumerate(self.clean):
            if ch == "\n":
                self._starts.append(k + 1)

    def pos(self, node: Any) -> SourcePos:
        p = node.position
        return SourcePos(self.file, int(p.lineno) + 1, int(p.column) + 1)

    def offset(self, node: Any) -> int:
        p = node.position
        return self._starts[int(p.lineno)] + int(p.column)

    def rule_text(self, node: Any) -> str:
        """Source of a WHERE/DERIVE expression starting at ``node`` (label stripped)."""
        text = _statement_text(self.clean, self.offset(node))
        return text


def _int_bound(expr: Any) -> int | None:
    if isinstance(expr, ast.IntegerLiteral):
        return int(expr.value)
    if isinstance(expr, ast.UnaryExpr) and isinstance(expr.operand, ast.IntegerLiteral):
        return -int(expr.operand.value) if expr.op is ast.UnaryOp.NEG else int(expr.operand.value)
    return None


class _Builder:
    def __init__(self, parsed: list[ParsedSchema]) -> None:
        self.parsed = parsed
        self.errors: list[SchemaError] = []
        self.decls: dict[str, Declaration] = {}
        self.schemas: dict[str, SchemaInfo] = {}
        self.texts = {id(p): _FileText(p) for p in parsed}
        self.functions: dict[str, str] = {}

    # -- conversion -------------------------------------------------------

    def error(self, message: str, pos: SourcePos | None, schema: str | None) -> None:
        self.errors.append(SchemaError(message, pos, schema))

    def type_ref(self, node: Any, ft: _FileText, schema: str) -> TypeRef:
        if isinstance(node, ast.NamedType):
            return NamedType(str(node.reference).lower())
        for simple_class, base in _SIMPLE.items():
            if isinstance(node, simple_class):
                width = getattr(node, "width", None) or getattr(node, "precision_spec", None)
                return SimpleType(base, _int_bound(width) if width is not None else None,
                                  bool(getattr(node, "fixed", False)))
        kinds: dict[type, AggregateKind] = {ast.ListType: "LIST", ast.SetType: "SET", ast.BagType: "BAG", ast.ArrayType: "ARRAY",
                 ast.ConformantListType: "LIST", ast.ConformantSetType: "SET",
                 ast.ConformantBagType: "BAG", ast.ConformantArrayType: "ARRAY"}
        for cls, kind in kinds.items():
            if isinstance(node, cls):
                return self.aggregate(node, kind, ft, schema)
        if isinstance(node, (ast.GenericType, ast.AggregateType)):
            label = getattr(node, "type_label", None) or getattr(node, "label", None)
            return GenericType(str(label).lower() if label else None)
        if isinstance(node, ast.GenericEntityType) if hasattr(ast, "GenericEntityType") else False:
            return GenericType(None)
        self.error(f"unsupported type construct {type(node).__name__}", ft.pos(node), schema)
        return GenericType(None)

    def aggregate(self, node: Any, kind: AggregateKind, ft: _FileText, schema: str) -> AggregateType:
        spec = node.bound_spec
        lower: int | None = 0
        upper: int | None = None
        bound_text = None
        if spec is not None:
            lower = _int_bound(spec.lower)
            upper = None if isinstance(spec.upper, ast.IndeterminateLiteral) else _int_bound(spec.upper)
            if lower is None or (upper is None and not isinstance(spec.upper, ast.IndeterminateLiteral)):
                bound_text = _statement_text(ft.clean, ft.offset(spec)).split("]")[0].lstrip("[ ")
        element = getattr(node, "of", None)
        return AggregateType(
            kind=kind,
            element=self.type_ref(element, ft, schema),
            lower=lower,
            upper=upper,
            unique=bool(getattr(node, "unique", False)),
            optional_elements=bool(getattr(node, "optional", False)),
            bound_text=bound_text,
        )

    def where_rules(self, rules: Iterable[Any], ft: _FileText) -> tuple[WhereRule, ...]:
        out = []
        for i, rule in enumerate(rules):
            label = str(rule.label) if rule.label else f"wr{i + 1}"
            out.append(WhereRule(label=label.lower(), source=ft.rule_text(rule.expr), expr=rule.expr,
                                 pos=ft.pos(rule)))
        return tuple(out)

    def supertype_expr(self, node: Any) -> SupertypeOperand:
        if isinstance(node, ast.NameRef):
            return str(node.identifier).lower()
        if isinstance(node, ast.Choice):
            return SupertypeExpr("ONEOF", tuple(self.supertype_expr(x) for x in node.supertype_exprs))
        assert isinstance(node, ast.SupertypeBinaryExpr)
        op: Literal["AND", "ANDOR"] = "AND" if node.op is ast.SupertypeBinaryOp.AND else "ANDOR"
        operands: list[SupertypeOperand] = []
        for side in (node.left, node.right):
            sub = self.supertype_expr(side)
            # Flatten a AND b AND c into one operator node.
            if isinstance(sub, SupertypeExpr) and sub.op == op:
                operands.extend(sub.operands)
            else:
                operands.append(sub)
        return SupertypeExpr(op, tuple(operands))

    def entity(self, node: Any, ft: _FileText, schema: str) -> Entity:
        name = str(node.identifier).lower()
        supertypes = tuple(str(n.identifier).lower() for n in node.subtype_declaration.of) \
            if node.subtype_declaration else ()
        abstract = False
        expr: SupertypeExpr | None = None
        sd = node.supertype_declaration
        if isinstance(sd, ast.AbstractSupertype):
            abstract = True
        elif isinstance(sd, ast.SupertypeOf):
            abstract = bool(sd.abstract)
            raw = self.supertype_expr(sd.of)
            expr = raw if isinstance(raw, SupertypeExpr) else SupertypeExpr("ANDOR", (raw,))
        attrs: list[Attribute] = []
        redecls: list[Redeclaration] = []
        for clause in node.explicit_clauses:
            type_ = self.type_ref(clause.type_selection, ft, schema)
            for ref in clause.attributes:
                if isinstance(ref, ast.QualifiedAttributeRef):
                    redecls.append(Redeclaration(name, str(ref.group_qualifier).lower(),
                                                 str(ref.attribute).lower(), type_, bool(clause.optional),
                                                 False, pos=ft.pos(ref)))
                else:
                    attrs.append(Attribute(str(ref.identifier).lower(), name, type_, "explicit",
                                           bool(clause.optional), pos=ft.pos(ref)))
        for derive in node.derive_clauses:
            for d in derive.derived_attributes:
                type_ = self.type_ref(d.type_selection, ft, schema)
                text = ft.rule_text(d.init)
                if isinstance(d.attribute, ast.QualifiedAttributeRef):
                    redecls.append(Redeclaration(name, str(d.attribute.group_qualifier).lower(),
                                                 str(d.attribute.attribute).lower(), type_, False, True,
                                                 pos=ft.pos(d)))
                else:
                    attrs.append(Attribute(str(d.attribute.identifier).lower(), name, type_, "derived",
                                           expression=text, pos=ft.pos(d)))
        for inverse_clause in node.inverse_clauses:
            for inv in inverse_clause.inverses:
                attrs.append(self.inverse(inv, name, ft, schema))
        uniques = tuple(
            UniqueRule(str(u.label).lower() if u.label else f"ur{i + 1}",
                       tuple(_attr_path(a) for a in u.attributes))
            for i, u in enumerate(node.unique_rules)
        )
        return Entity(name=name, schema=schema, supertypes=supertypes, abstract=abstract,
                      supertype_expr=expr, attributes=tuple(attrs), redeclarations=tuple(redecls),
                      unique_rules=uniques, where_rules=self.where_rules(node.domain_rules, ft),
                      pos=ft.pos(node))

    def inverse(self, inv: Any, entity: str, ft: _FileText, schema: str) -> Attribute:
        it = inv.inverse_type
        if isinstance(it, ast.NameRef):
            target = str(it.identifier).lower()
            type_: TypeRef = NamedType(target)
        else:
            target = str(it.entity).lower()
            kind: AggregateKind = "SET" if isinstance(it, ast.InverseSet) else "BAG"
            lower, upper = 0, None
            if it.bound_spec is not None:
                lower = _int_bound(it.bound_spec.lower) or 0
                upper = _int_bound(it.bound_spec.upper)
            type_ = AggregateType(kind, NamedType(target), lower, upper)
        forward = inv.attribute_ref
        fwd_name = _attr_path(forward).split(".")[-1]
        return Attribute(str(inv.attribute.identifier).lower(), entity, type_, "inverse",
                         inverse_of=(target, fwd_name), pos=ft.pos(inv))

    def type_decl(self, node: Any, ft: _FileText, schema: str) -> Declaration:
        name = str(node.identifier).lower()
        sel = node.type_selection
        rules = self.where_rules(node.domain_rules, ft)
        if isinstance(sel, ast.EnumType):
            return EnumerationType(name, schema, tuple(str(v).lower() for v in sel.values),
                                   where_rules=rules, pos=ft.pos(node))
        if isinstance(sel, ast.SelectType):
            return SelectType(name, schema, tuple(str(v.reference).lower() for v in sel.values),
                              where_rules=rules, pos=ft.pos(node))
        return DefinedType(name, schema, self.type_ref(sel, ft, schema), rules, ft.pos(node))

    def interfaces(self, tree: Any, ft: _FileText) -> tuple[Interface, ...]:
        out = []
        for ref in tree.reference_clauses:
            items = tuple((str(i.reference).lower(), str(i.alias or i.reference).lower())
                          for i in ref.import_list) or None
            out.append(Interface("REFERENCE", str(ref.schema_ref).lower(), items, ft.pos(ref)))
        for use in tree.use_clauses:
            items = tuple((str(i.reference).lower(), str(i.alias or i.reference).lower())
                          for i in use.use_list) or None
            out.append(Interface("USE", str(use.schema_ref).lower(), items, ft.pos(use)))
        return tuple(out)

    def add(self, decl: Declaration) -> None:
        previous = self.decls.get(decl.name)
        if previous is not None:
            self.error(f"duplicate name {decl.name!r}: already declared in schema "
                       f"{previous.schema!r} at {previous.pos}", decl.pos, decl.schema)
            return
        self.decls[decl.name] = decl

    def convert(self) -> None:
        for parsed in self.parsed:
            ft = self.texts[id(parsed)]
            tree = parsed.tree
            name = parsed.name
            if name in self.schemas:
                self.error(f"duplicate schema {name!r}", ft.pos(tree), name)
                continue
            declared: list[str] = []
            for node in tree.entity_declarations:
                decl = self.entity(node, ft, name)
                self.add(decl)
                declared.append(decl.name)
            for type_node in tree.type_declarations:
                tdecl = self.type_decl(type_node, ft, name)
                self.add(tdecl)
                declared.append(tdecl.name)
            self.schemas[name] = SchemaInfo(
                name=name, file=parsed.filename, interfaces=self.interfaces(tree, ft),
                declarations=tuple(declared),
                constants=tuple(str(c.identifier).lower() for c in tree.constant_definitions),
                functions=tuple(str(f.identifier).lower() for f in
                                list(tree.function_declarations) + list(tree.procedure_declarations)),
                rules=tuple(str(r.identifier).lower() for r in tree.rule_declarations),
            )


def _attr_path(node: Any) -> str:
    """``attr``, ``SELF\\e.attr`` or ``e.attr`` as a dotted lower-case path."""
    if isinstance(node, ast.NameRef):
        return str(node.identifier).lower()
    if isinstance(node, ast.QualifiedAttributeRef):
        return f"{str(node.group_qualifier).lower()}.{str(node.attribute).lower()}"
    if isinstance(node, ast.AttributeRef):
        return f"{_attr_path(node.source)}.{str(node.identifier).lower()}"
    return type(node).__name__.lower()


def build_model(parsed: list[ParsedSchema], catalog: dict[str, dict[str, Any]] | None = None) -> SchemaModel:
    """Resolve ``parsed`` schemas into one model; raise :class:`SchemaErrors` on problems.

    ``catalog`` maps a schema name to metadata (iso_part, title, edition,
    version, status, source, clauses) copied onto its :class:`SchemaInfo`.
    """
    b = _Builder(parsed)
    b.convert()
    for name, meta in (catalog or {}).items():
        info = b.schemas.get(name)
        if info is None:
            continue
        for key, value in meta.items():
            if key == "clauses":
                info.clauses = {k.lower(): str(v) for k, v in value.items()}
            elif hasattr(info, key) and key not in ("name", "file"):
                setattr(info, key, value)
    model = SchemaModel(b.schemas, b.decls)
    from stepnc_graph.schema.checks import check_model

    b.errors.extend(check_model(model))
    if b.errors:
        raise SchemaErrors(b.errors)
    return model
