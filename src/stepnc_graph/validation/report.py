"""Validation results and their three renderings: text, JSON, Turtle (``sh:ValidationReport``).

A result says where (graph, focus IRI, Part 21 ``#id``, entity, line,
attribute), what (offending value, a plain-language message), why (the rule:
an attribute's EXPRESS type, a WHERE rule's label and text, or a process
rule's name) and the ISO clause it comes from.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from html import escape
from dataclasses import asdict, dataclass, field
from typing import Any

SEVERITIES = ("Violation", "Warning", "Info")
SH_NS = "http://www.w3.org/ns/shacl#"


@dataclass(frozen=True)
class Result:
    """One finding. ``component`` is the SHACL constraint component IRI, or ``loader:<code>``."""

    severity: str
    graph: str
    focus: str
    p21_id: int | None
    entity: str | None
    line: int | None
    path: str | None
    value: str | None
    message: str
    rule: str | None
    clause: str | None
    component: str
    shape: str | None = None
    path_iri: str | None = field(default=None, compare=False)  # the path in SPARQL syntax (<iri> when simple)
    value_term: str | None = field(default=None, compare=False)  # the sh:value term (N-Triples)
    #: the RDF terms of the report (N-Triples; a blank node by the label of its graph)
    focus_term: str | None = field(default=None, compare=False)
    shape_term: str | None = field(default=None, compare=False)
    path_term: str | None = field(default=None, compare=False)  # the sh:path node of the shapes graph
    path_turtle: str | None = field(default=None, compare=False)  # that path written as Turtle
    message_terms: tuple[str, ...] = field(default=(), compare=False)  # every sh:resultMessage literal

    def asdict(self) -> dict[str, Any]:
        return {k: v for k, v in asdict(self).items() if k not in _TERMS}

    @property
    def sort_key(self) -> tuple[Any, ...]:
        return (self.graph, self.line if self.line is not None else 0, self.p21_id or 0,
                rank(self.severity), self.path or "", self.message, self.focus)

    @property
    def fails(self) -> bool:
        """Whether the result fails a program: a Violation, or a severity of one's own (SHACL
        allows any IRI; stepnc-graph does not guess that it is harmless)."""
        return rank(self.severity) == 0


_TERMS = ("path_iri", "value_term", "focus_term", "shape_term", "path_term", "path_turtle", "message_terms")


@dataclass(frozen=True)
class RuleCount:
    """How many results one rule gave: severity, attribute, rule (or component), clause, and the
    message of its first result."""

    count: int
    severity: str
    path: str
    rule: str
    clause: str
    message: str

    def asdict(self) -> dict[str, Any]:
        return asdict(self)


def rank(severity: str) -> int:
    """0 Violation (and custom severities), 1 Warning, 2 Info."""
    return SEVERITIES.index(severity) if severity in SEVERITIES else 0


@dataclass
class ValidationReport:
    """Every result of one validation, in report order (graph, line, #id)."""

    results: list[Result]
    graphs: list[str]
    checks_run: int = 0
    seconds: float = 0.0
    #: what the results alone do not say about how the data was checked (e.g. instances of another
    #: edition checked without that edition's rules: :func:`.editions.edition_notes`)
    notes: list[str] = field(default_factory=list)

    @property
    def conforms(self) -> bool:
        """SHACL's ``sh:conforms``: no result at all, of any severity (SHACL 3.6.1)."""
        return not self.results

    @property
    def passes(self) -> bool:
        """No Violation (nor a result of a custom severity): warnings and infos inform, they do not
        fail a program. The exit code follows this (see docs/validation.md)."""
        return not any(r.fails for r in self.results)

    def at_least(self, severity: str) -> "ValidationReport":
        """The results of ``severity`` or more severe."""
        level = SEVERITIES.index(severity)
        return ValidationReport([r for r in self.results if rank(r.severity) <= level], self.graphs,
                                self.checks_run, self.seconds, self.notes)

    def counts(self) -> dict[str, int]:
        out = {s: sum(r.severity == s for r in self.results) for s in SEVERITIES}
        out["Violation"] += sum(r.severity not in SEVERITIES for r in self.results)
        return out

    # -- renderings -----------------------------------------------------------------------

    def by_rule(self) -> list[RuleCount]:
        """How many results each rule gave (severity, attribute, rule, clause), most first: a
        program with one mistake repeated 3,704 times reads as one line here."""
        groups: dict[tuple[str, str, str, str], list[Result]] = {}
        for r in self.results:
            groups.setdefault((r.severity, r.path or "", r.rule or r.component, r.clause or ""), []).append(r)
        counts = [RuleCount(len(rs), *key, rs[0].message) for key, rs in groups.items()]
        return sorted(counts, key=lambda c: (-c.count, rank(c.severity), c.rule, c.path))

    def to_json(self, max_results: int | None = None) -> str:
        """The report as JSON; ``max_results`` keeps the first results (``omitted`` counts the rest)."""
        shown = self.results if max_results is None else self.results[:max_results]
        doc = {"conforms": self.conforms, "passes": self.passes, "graphs": self.graphs, "counts": self.counts(),
               "by_rule": [c.asdict() for c in self.by_rule()], "results": [r.asdict() for r in shown],
               "omitted": len(self.results) - len(shown), "notes": self.notes}
        return json.dumps(doc, indent=2, ensure_ascii=False) + "\n"

    def to_text(self, max_results: int | None = None) -> str:
        """Grouped by instance, sorted by line: ``line 23  #20 FACING_ROUGH  allowance: ...  [clause, rule]``,
        then how many results each rule gave. ``max_results`` lists the first results only.

        One line per result: a line break inside a message (a value from the program, a shapes
        file's ``sh:message``) is written ``\\n`` (``\\r``), so it can neither split a result
        nor pass for another one. The JSON and Turtle reports keep the text exactly.
        """
        lines: list[str] = []
        budget = len(self.results) if max_results is None else max_results
        for graph in self.graphs:
            mine = [r for r in self.results if r.graph == graph]
            c = {s: sum(r.severity == s for r in mine) for s in SEVERITIES}
            c["Violation"] += sum(r.severity not in SEVERITIES for r in mine)
            verdict = "conforms" if not mine else "passes (warnings only)" if not c["Violation"] else "does not conform"
            lines.append(f"{graph}: {verdict} "
                         f"({c['Violation']:,} violation(s), {c['Warning']:,} warning(s), {c['Info']:,} info)")
            for key, group in _by_instance(mine):
                group = group[:budget]
                budget -= len(group)
                if not group:
                    break
                line, ident, entity, focus = key
                if line is None and ident is None:  # not a Part 21 instance: name the node
                    lead = f"  {_short(focus)}"
                else:
                    head = f"line {line:<5}" if line is not None else "          "
                    lead = f"  {head} {f'#{ident}' if ident is not None else '':<7} {(entity or '').upper()}"
                for i, r in enumerate(group):
                    where = f"{r.path}: " if r.path else ""
                    cite = ", ".join(x for x in (r.clause, r.rule) if x)
                    tag = "" if r.severity == "Violation" else f"{_short(r.severity).lower()}: "
                    text = _one_line(f"{tag}{where}{r.message}{f'  [{cite}]' if cite else ''}")
                    lines.append(f"{lead}  {text}" if i == 0 else f"{' ' * len(lead)}  {text}")
        shown = len(self.results) if max_results is None else min(max_results, len(self.results))
        if shown < len(self.results):
            lines.append(f"... {len(self.results) - shown:,} more result(s) not listed (--max-results {shown:,})")
        lines += self._rule_lines()
        lines += [_one_line(f"note: {n}") for n in self.notes]
        return "\n".join(lines) + "\n"

    def _rule_lines(self) -> list[str]:
        """The per-rule summary of the text report, when there is more than one result."""
        if len(self.results) < 2:
            return []
        rules = self.by_rule()
        width = len(f"{rules[0].count:,}")
        out = [f"{len(self.results):,} result(s) by rule:"]
        for c in rules:
            where = f"{c.path}: " if c.path else ""
            cite = ", ".join(x for x in (c.clause, c.rule) if x)
            out.append(_one_line(f"  {c.count:>{width},}  {c.severity.lower():<9} {where}{c.message}"
                                 f"{f'  [{cite}]' if cite else ''}"))
        return out

    def __repr__(self) -> str:
        c = self.counts()
        return (f"<ValidationReport {'passes' if self.passes else 'fails'}: {c['Violation']:,} violation(s), "
                f"{c['Warning']:,} warning(s), {c['Info']:,} info in {len(self.graphs)} graph(s)>")

    def _repr_html_(self, max_results: int = 200) -> str:  # Jupyter
        """A notebook shows the verdict, the counts by rule and the first results as tables."""
        c = self.counts()
        verdict = "conforms" if self.conforms else "passes (warnings only)" if self.passes else "does not conform"
        head = (f"<p><b>{escape(verdict)}</b>: {c['Violation']:,} violation(s), {c['Warning']:,} warning(s), "
                f"{c['Info']:,} info in {len(self.graphs)} graph(s)</p>")
        rules = _table(["count", "severity", "path", "rule", "clause", "message"],
                       [[f"{r.count:,}", r.severity, r.path, r.rule, r.clause, r.message] for r in self.by_rule()])
        shown = self.results[:max_results]
        rows = _table(["severity", "line", "#id", "entity", "path", "value", "message", "rule", "clause"],
                      [[r.severity, "" if r.line is None else str(r.line), "" if r.p21_id is None else f"#{r.p21_id}",
                        r.entity or "", r.path or "", r.value or "", r.message, r.rule or "", r.clause or ""]
                       for r in shown])
        more = (f"<p>... {len(self.results) - len(shown):,} more result(s): <code>report.results</code></p>"
                if len(shown) < len(self.results) else "")
        return head + (rules + rows + more if self.results else "")

    def to_turtle(self) -> str:
        """The standard SHACL validation report."""
        out = ["@prefix sh: <http://www.w3.org/ns/shacl#> .",
               "@prefix p21: <https://w3id.org/stepnc-graph/p21#> .",
               *(["@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> ."] if self.notes else []), "",
               f"[] a sh:ValidationReport ; sh:conforms {'true' if self.conforms else 'false'}"
               + "".join(f" ;\n  rdfs:comment {_literal(n)}" for n in self.notes)]
        for r in self.results:
            severity = f"sh:{r.severity}" if r.severity in SEVERITIES else _term(r.severity)
            messages = r.message_terms or (_literal(r.message),)
            parts = [f"sh:focusNode {r.focus_term or _term(r.focus)}", f"sh:resultSeverity {severity}",
                     f"sh:sourceConstraintComponent {_term(r.component)}",
                     f"sh:resultMessage {', '.join(messages)}"]
            if r.path_turtle:
                parts.append(f"sh:resultPath {r.path_turtle}")
            elif r.path_iri and r.path_iri.startswith("<") and ">" not in r.path_iri[:-1]:
                parts.append(f"sh:resultPath {r.path_iri}")
            if r.value_term is not None:
                parts.append(f"sh:value {r.value_term}")
            if r.shape_term:
                parts.append(f"sh:sourceShape {r.shape_term}")
            elif r.shape:
                parts.append(f"sh:sourceShape {_term(r.shape)}")
            if r.p21_id is not None:
                parts.append(f"p21:id {r.p21_id}")
            if r.line is not None:
                parts.append(f"p21:line {r.line}")
            out.append(" ;\n  sh:result [ " + " ;\n      ".join(parts) + " ]")
        return "\n".join(out) + " .\n"


def _table(columns: list[str], rows: list[list[str]]) -> str:
    """An HTML table, every cell escaped (values come from the program and the shapes files)."""
    head = "".join(f"<th>{escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{escape(v)}</td>" for v in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _term(value: str) -> str:
    if value.startswith(("<", "_:")):
        return value
    if value.startswith("urn:bnode:"):
        return f"_:{value[10:]}"
    if value.startswith("loader:"):
        return f"<https://w3id.org/stepnc-graph/p21#diagnostic/{value[7:]}>"
    return f"<{value}>"


def _literal(text: str) -> str:
    """A Turtle string: backslash, quote and both line breaks escaped (Turtle allows neither raw)."""
    return '"' + _one_line(text.replace("\\", "\\\\").replace('"', '\\"')) + '"'


def _one_line(text: str) -> str:
    return text.replace("\r", "\\r").replace("\n", "\\n")


def _short(iri: str) -> str:
    """An IRI's local name for text output (a blank node label as it is)."""
    text = iri.strip("<>")
    for sep in ("#", "/"):
        if sep in text and not text.endswith(sep):
            text = text.rsplit(sep, 1)[1]
    return text


Group = tuple[int | None, int | None, str | None, str]


def _by_instance(results: Iterable[Result]) -> list[tuple[Group, list[Result]]]:
    groups: dict[Group, list[Result]] = {}
    for r in sorted(results, key=lambda r: r.sort_key):
        key = (r.line, r.p21_id, r.entity, r.focus if r.line is None and r.p21_id is None else "")
        groups.setdefault(key, []).append(r)
    return list(groups.items())
