"""SHACL-SPARQL query text: prefixes, pre-bound variables and the forms SHACL forbids (SHACL 5.3.1).

A constraint's query is read token by token (strings, IRIs, comments and
variables told apart), never by regular expressions over the whole text, so a
``$this`` inside a string or a ``{`` inside an IRI changes nothing. What this
module does with the tokens:

* **Prefixes.** The query's own ``PREFIX``/``BASE`` prologue and the
  ``sh:prefixes`` declarations of the shapes graph are applied here: every
  prefixed name becomes a full IRI, so a query can be nested in another
  query (a SPARQL constraint inside ``sh:node``) without its prologue, and an
  undeclared prefix is an error naming the constraint instead of a SPARQL
  syntax error at run time.
* **Refusals.** SHACL 5.3.1 defines pre-binding only for queries without
  ``MINUS``, ``VALUES`` (inline data), federated queries and ``AS ?var`` of a
  pre-bound variable, and whose sub-SELECTs return every pre-bound variable.
  A shapes graph using them is refused (:class:`~.shapes.IllFormedShapes`):
  the SHACL test suite requires an engine to fail on them. (``SERVICE``, a
  federated query, is refused by the project's query-safety check.)
* **Pre-binding.** SHACL defines ``$this`` as pre-bound: every occurrence,
  in every nested group, UNION branch and sub-SELECT, stands for the focus
  node. Running one query for all focus nodes, the engine puts the pattern
  binding ``?this`` to the focus nodes at the start of the WHERE clause *and*
  of every group a FILTER inside it could otherwise evaluate with ``?this``
  unbound: nested plain groups, UNION branches and sub-SELECTs. The joins on
  ``?this`` then equal substitution. ``FILTER EXISTS`` groups and OPTIONAL
  right-hand sides see the outer binding in Oxigraph already (tested), so they
  are left alone (the generated shapes' OPTIONALs stay as fast as they were).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from stepnc_graph.validation.shapes import IllFormedShapes, UnsupportedShapes

_TOKEN = re.compile(r"""
    (?P<ws>\s+)
  | (?P<comment>\#[^\n]*)
  | (?P<string>'''(?:[^'\\]|\\.|'(?!''))*'''|\"\"\"(?:[^"\\]|\\.|"(?!""))*\"\"\"|'(?:[^'\\\n]|\\.)*'|"(?:[^"\\\n]|\\.)*")
  | (?P<iri><[^<>"{}|^`\\\x00-\x20]*>)
  | (?P<var>[?$][A-Za-z_0-9\u00B7-\uFFFF]+)
  | (?P<pname>(?:[A-Za-z\u00C0-\uFFFF][\w\u00B7-\uFFFF.-]*)?:(?:[\w\u00B7-\uFFFF:%-]|\\.|\.(?=[\w:%-]))*)
  | (?P<langtag>@[A-Za-z]+(?:-[A-Za-z0-9]+)*)
  | (?P<number>[+-]?(?:\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?))
  | (?P<name>[A-Za-z_][A-Za-z_0-9]*)
  | (?P<punct>\^\^|&&|\|\||!=|<=|>=|[{}()\[\].,;*+/!=<>|^?&-])
""", re.VERBOSE)


@dataclass
class Token:
    kind: str
    text: str

    @property
    def upper(self) -> str:
        return self.text.upper() if self.kind == "name" else ""


def tokenize(text: str, where: str) -> list[Token]:
    """The tokens of a query (comments dropped, whitespace kept)."""
    out: list[Token] = []
    pos = 0
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if m is None:
            raise IllFormedShapes(f"{where}: the SPARQL query does not parse near {text[pos:pos + 30]!r}")
        kind = m.lastgroup or ""
        if kind != "comment":
            out.append(Token(kind, m.group()))
        pos = m.end()
    return out


def render(tokens: Iterable[Token]) -> str:
    return "".join(t.text for t in tokens)


def _significant(tokens: list[Token]) -> list[int]:
    return [i for i, t in enumerate(tokens) if t.kind != "ws"]


def apply_prologue(tokens: list[Token], prefixes: Mapping[str, str], where: str) -> list[Token]:
    """The tokens with the query's PREFIX/BASE prologue removed and every prefixed name written as a
    full IRI (the query's own prefixes first, then ``prefixes``: the shapes graph's ``sh:prefixes``)."""
    own: dict[str, str] = {}
    base = ""
    sig = _significant(tokens)
    k = 0
    cut = 0
    while k < len(sig):
        t = tokens[sig[k]]
        if t.upper == "PREFIX" and k + 2 < len(sig) and tokens[sig[k + 2]].kind == "iri":
            own[tokens[sig[k + 1]].text.rstrip(":")] = tokens[sig[k + 2]].text[1:-1]
            k += 3
        elif t.upper == "BASE" and k + 1 < len(sig) and tokens[sig[k + 1]].kind == "iri":
            base = tokens[sig[k + 1]].text[1:-1]
            k += 2
        else:
            break
        cut = sig[k - 1] + 1
    body = tokens[cut:]
    out: list[Token] = []
    for t in body:
        if t.kind == "pname":
            prefix, _, local = t.text.partition(":")
            ns = own.get(prefix, prefixes.get(prefix))
            if ns is None:
                raise IllFormedShapes(f"{where}: the prefix {prefix}: is not declared (sh:prefixes or PREFIX)")
            out.append(Token("iri", f"<{ns}{_unescape_local(local)}>"))
        elif t.kind == "iri" and base and not re.match(r"<[A-Za-z][A-Za-z0-9+.-]*:", t.text):
            from urllib.parse import urljoin

            out.append(Token("iri", f"<{urljoin(base, t.text[1:-1])}>"))
        else:
            out.append(t)
    return out


def _unescape_local(local: str) -> str:
    """A prefixed name's local part without its backslash escapes (``ex:a\\.b`` names ``a.b``)."""
    return re.sub(r"\\(.)", r"\1", local)


def _match_braces(tokens: list[Token], where: str) -> dict[int, int]:
    stack: list[int] = []
    pairs: dict[int, int] = {}
    for i, t in enumerate(tokens):
        if t.kind == "punct" and t.text == "{":
            stack.append(i)
        elif t.kind == "punct" and t.text == "}":
            if not stack:
                raise IllFormedShapes(f"{where}: unbalanced braces in the SPARQL query")
            pairs[stack.pop()] = i
    if stack:
        raise IllFormedShapes(f"{where}: unbalanced braces in the SPARQL query")
    return pairs


def _prev(tokens: list[Token], i: int) -> int | None:
    j = i - 1
    while j >= 0 and tokens[j].kind == "ws":
        j -= 1
    return j if j >= 0 else None


def _next(tokens: list[Token], i: int) -> int | None:
    j = i + 1
    while j < len(tokens) and tokens[j].kind == "ws":
        j += 1
    return j if j < len(tokens) else None


@dataclass
class Query:
    """A SELECT or ASK of a shapes graph, tokenized, prologue applied."""

    tokens: list[Token]
    where: str  # names the constraint in messages

    @classmethod
    def parse(cls, text: str, prefixes: Mapping[str, str], where: str) -> "Query":
        return cls(apply_prologue(tokenize(text, where), prefixes, where), where)

    def form(self) -> str:
        first = next((t.upper for t in self.tokens if t.kind != "ws"), "")
        return first

    def refuse_forbidden(self, prebound: Iterable[str]) -> None:
        """Raise for what SHACL 5.3.1 forbids in a query with pre-bound variables ``prebound``
        (names without ``?``/``$``)."""
        names = set(prebound)
        toks = self.tokens
        for i, t in enumerate(toks):
            if t.upper == "MINUS":
                raise IllFormedShapes(f"{self.where}: MINUS is not allowed in a SHACL-SPARQL query (SHACL 5.3.1)")
            if t.upper == "VALUES":
                raise IllFormedShapes(f"{self.where}: VALUES is not allowed in a SHACL-SPARQL query (SHACL 5.3.1)")
            if t.upper == "AS":
                n = _next(toks, i)
                if n is not None and toks[n].kind == "var" and toks[n].text[1:] in names:
                    raise IllFormedShapes(f"{self.where}: AS {toks[n].text} rebinds a pre-bound variable "
                                          f"(SHACL 5.3.1)")
        for start, end in self.subselects():
            if not self._projects(start, end, "this") and "this" in names:
                raise IllFormedShapes(f"{self.where}: a sub-SELECT must return $this (SHACL 5.3.1)")

    def subselects(self) -> list[tuple[int, int]]:
        """(index of SELECT, index of the closing brace of its WHERE group) of each sub-SELECT."""
        pairs = _match_braces(self.tokens, self.where)
        out = []
        first = True
        for i, t in enumerate(self.tokens):
            if t.upper == "SELECT":
                if first:
                    first = False
                    continue
                body = self._where_open(i)
                out.append((i, pairs[body]))
        return out

    def _where_open(self, select: int) -> int:
        for j in range(select + 1, len(self.tokens)):
            if self.tokens[j].kind == "punct" and self.tokens[j].text == "{":
                return j
        raise IllFormedShapes(f"{self.where}: a SELECT without WHERE group")

    def _projects(self, select: int, end: int, name: str) -> bool:
        """Whether the SELECT at ``select`` returns ``?name``: listed, or ``*`` with the variable in
        scope (used outside FILTER expressions of its WHERE group)."""
        body = self._where_open(select)
        head = [t for t in self.tokens[select + 1:body] if t.kind != "ws"]
        if any(t.kind == "var" and t.text[1:] == name for t in head):
            return True
        if not any(t.text == "*" for t in head):
            return False
        depth_in_filter = 0
        paren = 0
        for t in self.tokens[body:end]:
            if t.upper in ("FILTER",):
                depth_in_filter = 1
                paren = 0
                continue
            if depth_in_filter:
                if t.text == "(":
                    paren += 1
                elif t.text == ")":
                    paren -= 1
                    if paren == 0:
                        depth_in_filter = 0
                continue
            if t.kind == "var" and t.text[1:] == name:
                return True
        return False

    def uses(self, name: str) -> bool:
        return any(t.kind == "var" and t.text[1:] == name for t in self.tokens)

    def substitute(self, values: Mapping[str, str]) -> "Query":
        """Variables ``$name``/``?name`` replaced by terms or other variables (``values`` by name)."""
        out = [Token("raw", values[t.text[1:]]) if t.kind == "var" and t.text[1:] in values else t
               for t in self.tokens]
        return Query(out, self.where)

    def replace_path(self, path: str | None) -> "Query":
        """``$PATH`` as the property shape's path (SHACL 5.3.1); refused on a node shape."""
        if not any(t.kind == "var" and t.text == "$PATH" for t in self.tokens):
            return self
        if path is None:
            raise IllFormedShapes(f"{self.where}: $PATH in a SPARQL query of a node shape")
        return Query([Token("raw", path) if t.kind == "var" and t.text == "$PATH" else t for t in self.tokens],
                     self.where)

    def where_group(self) -> tuple[int, int]:
        """Indices of the braces of the top-level WHERE group."""
        pairs = _match_braces(self.tokens, self.where)
        for i, t in enumerate(self.tokens):
            if t.kind == "punct" and t.text == "{":
                return i, pairs[i]
        raise IllFormedShapes(f"{self.where}: no WHERE group")

    def with_focus(self, focus: Callable[[], str], var: str = "?this") -> str:
        """The query text with ``focus()`` (a pattern binding ``var``) at the start of its WHERE group
        and of every group that holds ``var`` and is evaluated on its own: plain nested groups,
        UNION branches and sub-SELECTs (see the module docstring)."""
        toks = self.tokens
        pairs = _match_braces(toks, self.where)
        top, _ = self.where_group()
        name = var[1:]
        inject: set[int] = {top}
        for open_, close in pairs.items():
            if open_ == top:
                continue
            if not any(t.kind in ("var",) and t.text[1:] == name or (t.kind == "raw" and t.text == var)
                       for t in toks[open_:close]):
                continue
            p = _prev(toks, open_)
            before = toks[p] if p is not None else None
            n = _next(toks, open_)
            if before is None or (n is not None and toks[n].upper == "SELECT"):
                continue  # a sub-SELECT's own group holds the SELECT alone: its WHERE group gets the focus
            keyword = before.upper
            if keyword in ("EXISTS", "OPTIONAL", "GRAPH", "SERVICE", "MINUS") or before.kind in ("iri", "var", "raw"):
                continue  # EXISTS and OPTIONAL see the outer binding; GRAPH and SERVICE are other data
            if keyword == "WHERE" or before.text in ("{", "}", ".") or keyword == "UNION":
                inject.add(open_)
            elif before.kind == "punct" and before.text == ")":
                inject.add(open_)  # SELECT ... (expr AS ?x) { ... } without WHERE
        out: list[str] = []
        for i, t in enumerate(toks):
            out.append(t.text)
            if i in inject:
                out.append(f" {focus()} ")
        return "".join(out)

    def ensure_projected(self, var: str) -> "Query":
        """Add ``var`` to the top-level SELECT's projection unless it is there or the SELECT is ``*``."""
        toks = self.tokens
        sig = _significant(toks)
        if not sig or toks[sig[0]].upper != "SELECT":
            return self
        top, _ = self.where_group()
        head = [t for t in toks[sig[0] + 1:top] if t.kind != "ws"]
        if any(t.text == "*" for t in head) or any(t.kind in ("var", "raw") and t.text in (var, "$" + var[1:])
                                                    for t in head):
            return self
        k = sig[0] + 1
        n = _next(toks, sig[0])
        if n is not None and toks[n].upper in ("DISTINCT", "REDUCED"):
            k = n + 1
        return Query(toks[:k] + [Token("raw", f" {var} ")] + toks[k:], self.where)

    def where_body(self) -> str:
        """The text inside the top-level WHERE group (for a constraint nested in a boolean test)."""
        start, end = self.where_group()
        sig = _significant(self.tokens)
        after = [self.tokens[i] for i in sig if i > end]
        head = [self.tokens[i] for i in sig if i < start]
        if after or any(t.upper in ("GROUP", "HAVING", "ORDER", "LIMIT", "OFFSET") for t in head) or \
                any(t.text == "(" for t in head):
            raise UnsupportedShapes(f"{self.where}: a SPARQL constraint with solution modifiers or expressions "
                                    f"in its SELECT is run only where its shape has targets, not inside "
                                    f"sh:node, sh:not, sh:and, sh:or, sh:xone or sh:qualifiedValueShape")
        return render(self.tokens[start + 1:end])

    def text(self) -> str:
        return render(self.tokens)


def term_text(term: str) -> str:
    """An N-Triples term as SPARQL text (IRIs and literals are the same; a blank node is not a term in SPARQL)."""
    if term.startswith("_:"):
        raise UnsupportedShapes(f"a blank node ({term}) cannot be given to a SPARQL query as a value")
    return term
