"""Query parameters as ``VALUES`` inside the query's groups, for a store reached over the protocol.

The embedded store binds a parameter the way pyoxigraph's ``substitutions`` do
(SPARQL SEP-0007): evaluation starts from a solution that already binds the
variable, so every pattern and FILTER of the query sees the value -- in nested
groups, UNION branches, OPTIONAL, MINUS, EXISTS, and sub-SELECTs that project the
variable; a sub-SELECT that does not project it has a variable of its own.
Standard SPARQL 1.1 has no such pre-binding, and a ``VALUES`` clause after the
query (where it used to go) is joined after the WHERE clause's FILTERs ran, so
they saw the variable unbound and dropped every row.

:func:`bind_in_groups` gives a remote store the same meaning: a one-row
``VALUES`` block opens every group graph pattern the variable's scope reaches
(as above), so each group is joined with the value before its FILTERs apply.
The groups are found by a SPARQL tokenizer (SPARQL 1.1 Query, 19.8: longest
match, so strings, IRIs and comments never count as braces); the caller checks
the rewritten text with Oxigraph's parser.
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping
from dataclasses import dataclass

_TOKEN = re.compile(r"""
    (?P<space>\s+)
  | (?P<comment>\#[^\n\r]*)
  | (?P<string>\"\"\"(?:[^"\\]|\\.|"(?!""))*\"\"\"|'''(?:[^'\\]|\\.|'(?!''))*'''
      |"(?:[^"\\\n\r]|\\.)*"|'(?:[^'\\\n\r]|\\.)*')
  | (?P<iri><[^<>"{}|^`\\\x00-\x20]*>)
  | (?P<var>[?$][A-Za-z0-9_\u00B7\u00C0-\uFFFF]+)
  | (?P<word>[A-Za-z_\u00C0-\uFFFF][A-Za-z0-9_.\-\u00B7\u00C0-\uFFFF]*(?::[^\s{}()\[\],;"'<>]*)?|:[^\s{}()\[\],;"'<>]*)
  | (?P<punct>[{}()])
  | (?P<other>.)
""", re.VERBOSE | re.DOTALL)


@dataclass(frozen=True)
class _Token:
    kind: str  # var, word, punct or other (strings, IRIs, numbers, operators)
    text: str
    end: int  # offset just after the token


def _tokens(text: str) -> Iterator[_Token]:
    """The significant tokens of a SPARQL text (no spaces or comments)."""
    for match in _TOKEN.finditer(text):
        kind = match.lastgroup or "other"
        if kind in ("space", "comment"):
            continue
        yield _Token("other" if kind in ("string", "iri") else kind, match.group(), match.end())


def _projects(tokens: list[_Token], start: int, names: set[str]) -> tuple[bool, int]:
    """Whether the SELECT clause starting at ``tokens[start]`` projects one of ``names``, and the
    index of the brace opening its WHERE group. ``SELECT *`` projects the variables in scope in
    its WHERE group (SPARQL 1.1 Query, 18.2.1): not one that only a FILTER or an expression uses."""
    depth, star, i = 0, False, start + 1
    while i < len(tokens):
        token = tokens[i]
        if token.text == "(":
            depth += 1
        elif token.text == ")":
            depth -= 1
        elif token.text == "{" and depth == 0:
            return (_in_scope(tokens, i, names) if star else False), i
        elif depth == 0 and token.text == "*":
            star = True
        elif depth == 0 and token.kind == "var" and token.text[1:] in names:
            return True, _where(tokens, i)
        i += 1
    return False, i


def _where(tokens: list[_Token], i: int) -> int:
    """The index of the first brace outside parentheses from ``tokens[i]`` on."""
    depth = 0
    while i < len(tokens) and not (tokens[i].text == "{" and depth == 0):
        depth += {"(": 1, ")": -1}.get(tokens[i].text, 0)
        i += 1
    return i


def _in_scope(tokens: list[_Token], start: int, names: set[str]) -> bool:
    """Whether a variable of ``names`` is in scope in the group opening at ``tokens[start]``: it
    stands in a pattern (outside parentheses), is bound by ``AS`` or listed by ``VALUES``."""
    braces, parens, values_list = 0, 0, False
    for i in range(start, len(tokens)):
        token = tokens[i]
        text = token.text.upper()
        if text == "{":
            braces += 1
            values_list = False
        elif text == "}":
            braces -= 1
            if braces == 0:
                return False
        elif text == "(":
            parens += 1
        elif text == ")":
            parens -= 1
        elif token.kind == "word" and text == "VALUES":
            values_list = True
        elif token.kind == "var" and token.text[1:] in names and (
                parens == 0 or values_list or tokens[i - 1].text.upper() == "AS"):
            return True
    return False


def group_openings(text: str, names: set[str]) -> list[int]:
    """Offsets just after each ``{`` that opens a group the variables ``names`` reach (see the
    module docstring), in a SELECT query."""
    tokens = list(_tokens(text))
    openings: list[int] = []
    braces: list[str] = []  # per open brace: "group", "select" (holds a sub-SELECT) or "data" (VALUES)
    scopes: list[bool] = [True]  # per SELECT, inner first: whether its groups get the values
    data_next = False
    i = 0
    while i < len(tokens):
        token = tokens[i]
        upper = token.text.upper()
        if token.kind == "word" and upper == "VALUES":
            data_next = True
        elif token.kind == "word" and upper == "SELECT" and braces and braces[-1] == "select":
            projects, where = _projects(tokens, i, names)
            scopes.append(scopes[-1] and projects)
            i = where
            continue
        elif token.text == "{":
            if data_next:
                braces.append("data")
                data_next = False
            elif i + 1 < len(tokens) and tokens[i + 1].kind == "word" and tokens[i + 1].text.upper() == "SELECT":
                braces.append("select")
            else:
                braces.append("group")
                if scopes[-1] and "data" not in braces:
                    openings.append(token.end)
        elif token.text == "}" and braces:
            if braces.pop() == "select":
                scopes.pop()
        i += 1
    return openings


def bind_in_groups(text: str, terms: Mapping[str, str]) -> str:
    """``text`` (a SELECT query) with ``VALUES (?name ...) { (term ...) }`` opening every group the
    variables reach; ``terms`` maps variable names to terms in SPARQL syntax."""
    block = f" VALUES ({' '.join('?' + n for n in terms)}) {{ ({' '.join(terms.values())}) }} "
    out, last = [], 0
    for offset in group_openings(text, set(terms)):
        out += [text[last:offset], block]
        last = offset
    return "".join(out) + text[last:]
