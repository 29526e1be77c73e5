"""Random schema-valid Part 21 programs, for property-based tests and fuzzing.

``random_program(seed)`` picks concrete entities of the shipped schemas and
fills every parameter with a value of the attribute's type -- references to
instances of a fitting (non-abstract) class, enumeration items, typed values
inside SELECTs, lists within their bounds, awkward strings -- so that loading
it must give zero diagnostics and the Part 21 round trip must be exact. The
text is written here, independently of :mod:`stepnc_graph.mapping.writer`.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field

from stepnc_graph.mapping.plans import Encoding, Plans, iso14649_plans
from stepnc_graph.part21.strings import encode
from stepnc_graph.schema.model import Entity

_TEXT = ["", "a", "it's", "back\\slash", "caf\u00e9", "\u4e2d\u6587", "emoji \U0001F600", "semi;colon",
         "comma, (paren)", "#12=X();", "/* not a comment */", "$", "*"]


def _real(rng: random.Random) -> str:
    value = rng.choice([0.0, 1.0, -2.5, 1e-7, 123456.789, rng.uniform(-1000, 1000)])
    text = repr(value)
    if "e" in text:
        m, e = text.split("e")
        return (m if "." in m else m + ".") + "E" + e
    return text


@dataclass
class _Program:
    rng: random.Random
    plans: Plans
    lines: list[str] = field(default_factory=list)
    by_class: dict[str, list[int]] = field(default_factory=dict)
    next_id: int = 1
    budget: int = 60

    def concrete(self, entity: str) -> list[str]:
        model = self.plans.model
        names = [entity, *model.all_subtypes(entity)]
        return [n for n in names if not model.entity(n).abstract]

    def instance_of(self, candidates: list[str], depth: int) -> int | None:
        if not candidates:
            return None
        existing = [i for c in candidates for i in self.by_class.get(c, [])]
        if existing and (depth > 2 or self.budget <= 0 or self.rng.random() < 0.3):
            return self.rng.choice(existing)
        if self.budget <= 0 and depth > 6:
            return None
        return self.make(self.rng.choice(candidates), depth + 1)

    def make(self, entity: str, depth: int = 0) -> int | None:
        plan = self.plans.entities[entity.upper()]
        ident = self.next_id
        self.next_id += 1
        self.budget -= 1
        params = []
        for slot in plan.slots:
            if slot.derived:
                params.append("*")
                continue
            if slot.optional and (depth > 3 or self.rng.random() < 0.3):
                params.append("$")
                continue
            if slot.repeated:
                members = [self.value(slot.encoding, depth) for _ in range(self.rng.randint(0, 3))]
                values = list(dict.fromkeys(m for m in members if m is not None))  # a SET has no duplicates
                params.append("(" + ",".join(values) + ")")
                continue
            value = self.value(slot.encoding, depth)
            if value is None:
                if not slot.optional:  # no instance can fill a mandatory slot: give up on this entity
                    return None
                value = "$"
            params.append(value)
        self.lines.append(f"#{ident}={entity.upper()}({','.join(params)});")
        self.by_class.setdefault(entity, []).append(ident)  # only complete instances are referenced
        return ident

    def value(self, enc: Encoding, depth: int) -> str | None:
        rng = self.rng
        kind = enc.kind
        if kind == "integer":
            return str(rng.randint(-5, 500))
        if kind == "real":
            return _real(rng)
        if kind == "string":
            return encode(rng.choice(_TEXT))
        if kind == "boolean":
            return rng.choice([".T.", ".F."])
        if kind == "logical":
            return rng.choice([".T.", ".F.", ".U."])
        if kind == "binary":
            return '"0' + rng.choice(["", "0F", "A1B2"]) + '"'
        if kind == "enum":
            return "." + rng.choice(sorted(enc.items)) + "."
        if kind == "entity":
            ref = self.instance_of(self.concrete(enc.label), depth)
            return None if ref is None else f"#{ref}"
        if kind == "list":
            assert enc.element is not None
            low = enc.lower or 0
            high = enc.upper if enc.upper is not None else low + 3
            count = rng.randint(low, max(low, min(high, low + 3)))
            items = [self.value(enc.element, depth + 1) for _ in range(count)]
            if any(i is None for i in items):
                return None
            return "(" + ",".join(i for i in items if i is not None) + ")"
        if kind == "select":
            return self._select(enc, depth)
        return None

    def _select(self, enc: Encoding, depth: int) -> str | None:
        options = []
        if enc.accepts_refs:
            options.append("ref")
        if enc.items:
            options.append("enum")
        if enc.typed:
            options.append("typed")
        self.rng.shuffle(options)
        model = self.plans.model
        for option in options:
            if option == "enum":
                return "." + self.rng.choice(sorted(enc.items)) + "."
            if option == "typed":
                name = self.rng.choice(sorted(enc.typed))
                inner = self.value(enc.typed[name][1], depth + 1)
                if inner is not None:
                    return f"{name}({inner})"
            if option == "ref":
                sel = model.select_behind(enc.label)
                members = model.select_closure(sel.name) if sel else ()
                candidates = [c for m in members if isinstance(model[m], Entity) for c in self.concrete(m)]
                ref = self.instance_of(candidates, depth)
                if ref is not None:
                    return f"#{ref}"
        return None


def random_program(seed: int, roots: int = 3, schemas: tuple[str, ...] = ("turning_schema",
                                                                          "turning_machine_tool_schema")) -> str:
    """A schema-valid Part 21 program; the same seed always gives the same text."""
    plans = iso14649_plans()
    model = plans.model
    rng = random.Random(seed)
    prog = _Program(rng, plans)
    pool = sorted(e.name for s in schemas for e in model.in_schema(s)
                  if isinstance(e, Entity) and not e.abstract)
    made = 0
    attempts = 0
    while made < roots and attempts < roots * 20:
        attempts += 1
        prog.budget = 60
        if prog.make(rng.choice(pool)) is not None:
            made += 1
    header = ("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('random schema-valid program'),'2;1');\n"
              f"FILE_NAME('random_{seed}.stp','',(''),(''),'stepnc-graph synth','','');\n"
              "FILE_SCHEMA(('MACHINING_SCHEMA','TURNING_SCHEMA','TURNING_MACHINE_TOOL_SCHEMA'));\nENDSEC;\n")
    return header + "DATA;\n" + "\n".join(prog.lines) + "\nENDSEC;\nEND-ISO-10303-21;\n"
