"""The compiler of one domain rule of one entity (:mod:`.express_sparql`): attributes followed through
the model, and expressions compiled to the values they denote; the logical expressions are in
:mod:`.express_logic`.
"""

from __future__ import annotations

import itertools
from typing import Any

import express_schema.parse as ast

from stepnc_graph.core.naming import P21_NS, Naming
from stepnc_graph.schema.model import (
    AggregateType,
    Attribute,
    BaseType,
    Entity,
    NamedType,
    SimpleType,
    TypeRef,
)
from stepnc_graph.schema.view import SchemaModel
from stepnc_graph.vocabulary.typemap import value_shape
from stepnc_graph.generators.express_logic import Conditions
from stepnc_graph.generators.express_terms import (RDF_NS, Untranslatable, Agg, OPS, PathValue, Scalar, Scope,
                                                 Value, literal_number)


class RuleCompiler:
    """Compiles one rule of one entity; raises Untranslatable on the first construct it cannot render."""

    def __init__(self, model: SchemaModel, naming: Naming, entity: Entity) -> None:
        self.model = model
        self.n = naming
        self.entity = entity
        self.counter = itertools.count(1)
        self.scope = Scope()
        self.vars: dict[str, tuple[str, TypeRef]] = {}  # query variable -> (SPARQL var, element type)
        self.self_members: set[str] = set()  # SPARQL vars ranging over an aggregate attribute of SELF
        self.notes: list[str] = []
        #: SET index variables: members pattern -> (the SET, index -> variable)
        self.set_indexed: dict[str, tuple[Agg, dict[int, str]]] = {}
        self.set_hits = 0
        self.last_comparison_strict = False
        #: the rule's logical expressions (the values they test come from here)
        self.logic = Conditions(self)

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

    def step(self, base: PathValue, a: Attribute) -> Value:
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
            return PathValue(base.root, base.steps + (p,), a.type)
        agg = self.model.base_type(a.type)
        assert isinstance(agg, AggregateType)
        prefix = base.steps
        root = base.root
        if shape.form == "repeated":
            def set_members(c: RuleCompiler, m: str, cell: str) -> str:
                return f"{root} {'/'.join(prefix + (p,))} {m} ."
            owner = self.fresh("o")
            head = f"{root} {'/'.join(prefix)} {owner} ." if prefix else ""
            subject = owner if prefix else root
            present = (f"EXISTS {{ {head} {{ {subject} {p} ?any }} UNION "
                       f"{{ {subject} <{P21_NS}emptyAggregate> {p} }} }}")
            return Agg(set_members, agg.element, False, present)

        def list_members(c: RuleCompiler, m: str, cell: str) -> str:
            return f"{root} {'/'.join(prefix + (p,))}/<{RDF_NS}rest>* {cell} . {cell} <{RDF_NS}first> {m} ."
        return Agg(list_members, agg.element, True, f"EXISTS {{ {root} {'/'.join(prefix + (p,))} ?any }}",
                    PathValue(root, prefix + (p,), a.type))

    def dimension(self, base: PathValue) -> Scalar:
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
        return Scalar(dim, SimpleType(BaseType.INTEGER))

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

    def materialize(self, v: Value) -> str:
        """A SPARQL variable (or term) holding the value; unbound when it is indeterminate."""
        if isinstance(v, Scalar):
            return v.expr
        if isinstance(v, Agg):
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

    def value(self, e: Any) -> Value:
        if isinstance(e, ast.Self):
            return PathValue("$this", (), NamedType(self.entity.name), always=True)
        if isinstance(e, ast.NameRef):
            name = str(e.identifier).lower()
            if name in self.vars:
                var, t = self.vars[name]
                return PathValue(var, (), t, always=True)
            return self.step(PathValue("$this", (), NamedType(self.entity.name), always=True),
                             self.attribute(NamedType(self.entity.name), name))
        if isinstance(e, (ast.AttributeRef, ast.QualifiedAttributeRef)):
            base = self.value(e.source)
            if not isinstance(base, PathValue):
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
                isinstance(e, ast.UnaryExpr) and e.op is ast.UnaryOp.NEG and literal_number(e) is not None):
            n = literal_number(e)
            return Scalar(str(n) if isinstance(n, int) else f"{n}e0", None)
        if isinstance(e, ast.StringLiteral):
            return Scalar('"' + str(e.value).replace("\\", "\\\\").replace('"', '\\"') + '"', None)
        if isinstance(e, ast.BinaryExpr) and e.op in (ast.BinaryOp.ADD, ast.BinaryOp.SUBTRACT,
                                                       ast.BinaryOp.MULTIPLY, ast.BinaryOp.REAL_DIVIDE):
            if isinstance(e.left, ast.AggregateLiteral) or isinstance(e.right, ast.AggregateLiteral):
                raise Untranslatable("an aggregate literal in arithmetic (set intersection with TYPEOF)")
            left, right = self.scalar(e.left), self.scalar(e.right)
            return Scalar(f"({left} {OPS[e.op]} {right})", None)
        if isinstance(e, ast.Call) and self.callee(e) == "sizeof":
            raise Untranslatable("SIZEOF compared with something other than a literal integer")
        return Scalar(self.logic.boolean(e), None)

    def scalar(self, e: Any) -> str:
        return self.materialize(self.value(e))

    def callee(self, e: ast.Call) -> str:
        return str(e.callee.identifier).lower() if isinstance(e.callee, ast.NameRef) else ""

    def index(self, e: ast.IndexExpr) -> Value:
        base = self.value(e.source)
        i = literal_number(e.index)
        if not isinstance(base, Agg) or not isinstance(i, int) or i < 1:
            raise Untranslatable("an index that is not a literal position in an aggregate attribute")
        if not base.is_list:
            return self.set_member(base, i)
        if base.head is None:
            raise Untranslatable("indexes a computed aggregate")
        # the i-th member is rdf:first of the cell reached by i-1 rdf:rest steps
        steps = base.head.steps + (f"<{RDF_NS}rest>",) * (i - 1) + (f"<{RDF_NS}first>",)
        return PathValue(base.head.root, steps, base.element)

    def set_member(self, agg: Agg, i: int) -> PathValue:
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
        return PathValue(slots[i], (), agg.element, always=True)

    def query(self, e: ast.QueryExpr) -> Agg:
        source = self.value(e.aggregate)
        if not isinstance(source, Agg):
            raise Untranslatable("QUERY over a value that is not an aggregate attribute")
        name = str(e.variable).lower()
        predicate = e.predicate
        of_self = self.is_self_aggregate(e.aggregate)

        def members(c: RuleCompiler, m: str, cell: str) -> str:
            inner = source.members(c, m, cell)
            saved_scope, saved_vars = c.scope, dict(c.vars)
            c.scope = Scope([inner])
            c.vars[name] = (m, source.element)
            if of_self:
                c.self_members.add(m)
            try:
                cond = c.logic.boolean(predicate)
                return c.scope.text([cond])
            finally:
                c.scope, c.vars = saved_scope, saved_vars
        return Agg(members, source.element, source.is_list, source.present)

    def is_self_aggregate(self, e: Any) -> bool:
        """``SELF.attr`` or ``attr`` (an attribute of SELF itself)."""
        if isinstance(e, ast.NameRef):
            return str(e.identifier).lower() not in self.vars
        return isinstance(e, ast.AttributeRef) and isinstance(e.source, ast.Self)
