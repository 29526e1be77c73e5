"""SPARQL syntax errors that name the cause, not the parser's last alternative.

Oxigraph's parser reports the furthest point it reached and the tokens it tried there: for
``SELEKT`` that is "expected CONSTRUCT" (the last of the query forms it tried), for a missing
``)`` a list of function names, for an unfinished triple the RDF-star tokens. What a reader needs
is the cause, which the text shows by itself in the common cases, checked here in this order:

1. the query form: the first word after the prologue must be SELECT, CONSTRUCT, ASK or DESCRIBE;
   an update (INSERT, DELETE, DROP, ...) is refused as such -- queries are read-only -- and another
   word gets "did you mean";
2. a string not closed on its line, or a bracket never closed or closed without being opened
   (positioned where it opened);
3. otherwise the parser's own position with what is found there, and the tokens it expected
   without the RDF-star and extension tokens (``<<``, ``{|``, ``~``, ``LATERAL``) and character
   classes that only confuse.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass

FORMS = ("SELECT", "CONSTRUCT", "ASK", "DESCRIBE")
UPDATES = ("INSERT", "DELETE", "LOAD", "CLEAR", "CREATE", "DROP", "COPY", "MOVE", "ADD", "WITH")
#: Tokens of SPARQL 1.2 / RDF-star and Oxigraph's extensions: listing them as "expected" misleads.
_NOISE = {'"<<"', '"<<("', '"{|"', '"|}"', '"~"', '">>"', '")>>"', "LATERAL", "[_]"}

_LEX = re.compile(
    r'(?P<space>\s+)|(?P<comment>#[^\n]*)'
    r'|(?P<string>(?:"""(?:[^"\\]|\\.|"(?!""))*"""|\'\'\'(?:[^\'\\]|\\.|\'(?!\'\'))*\'\'\''
    r'|"(?:[^"\\\n]|\\.)*"|\'(?:[^\'\\\n]|\\.)*\')(?:@[\w-]+|\^\^\S+?(?=[\s.,;)}\]]|$))?)'
    r'|(?P<open_string>["\'])'
    r'|(?P<iri><[^<>"{}|^`\\\s]*>)'
    r'|(?P<bracket>[(){}\[\]])'
    r'|(?P<punct>[,;]|\.(?=[\s(){}\[\]#]|$))'
    r'|(?P<run>[^\s(){}\[\]"\'#<,;]*[^\s(){}\[\]"\'#<,;.]|<)')
_PAIRS = {")": "(", "}": "{", "]": "["}
#: Keywords a mistyped word is compared with ("LIMT": did you mean LIMIT?).
KEYWORDS = (*FORMS, "WHERE", "FROM", "NAMED", "LIMIT", "OFFSET", "ORDER", "GROUP", "BY", "HAVING", "VALUES",
            "FILTER", "OPTIONAL", "UNION", "MINUS", "BIND", "GRAPH", "SERVICE", "SILENT", "DISTINCT", "REDUCED",
            "EXISTS", "NOT", "IN", "AS", "ASC", "DESC", "PREFIX", "BASE", "UNDEF", "SEPARATOR", "LATERAL")
#: The built-in functions and aggregates of SPARQL 1.1 (and Oxigraph's triple-term functions).
FUNCTIONS = ("STR", "LANG", "LANGMATCHES", "DATATYPE", "BOUND", "IRI", "URI", "BNODE", "RAND", "ABS", "CEIL",
             "FLOOR", "ROUND", "CONCAT", "STRLEN", "UCASE", "LCASE", "ENCODE_FOR_URI", "CONTAINS", "STRSTARTS",
             "STRENDS", "STRBEFORE", "STRAFTER", "YEAR", "MONTH", "DAY", "HOURS", "MINUTES", "SECONDS", "TIMEZONE",
             "TZ", "NOW", "UUID", "STRUUID", "MD5", "SHA1", "SHA256", "SHA384", "SHA512", "COALESCE", "IF", "STRLANG",
             "STRDT", "SAMETERM", "ISIRI", "ISURI", "ISBLANK", "ISLITERAL", "ISNUMERIC", "REGEX", "SUBSTR", "REPLACE",
             "COUNT", "SUM", "MIN", "MAX", "AVG", "SAMPLE", "GROUP_CONCAT", "TRIPLE", "SUBJECT", "PREDICATE",
             "OBJECT", "ISTRIPLE", "LANGDIR", "STRLANGDIR", "HASLANG", "HASLANGDIR")
_WORDS = frozenset((*KEYWORDS, *FUNCTIONS, "A", "TRUE", "FALSE"))
#: Keywords after which a group's triples stop being checked for completeness until the next ``.``/``{``/``}``.
_NOT_TRIPLES = frozenset({"FILTER", "BIND", "VALUES", "OPTIONAL", "MINUS", "UNION", "GRAPH", "SERVICE", "EXISTS",
                          "NOT", "SELECT", "LATERAL"})
_NEEDED = {"{": 3, ".": 3, ";": 2, ",": 1}


def _tokens(text: str) -> list[re.Match[str]]:
    return [m for m in _LEX.finditer(text) if m.lastgroup not in ("space", "comment")]


@dataclass(frozen=True)
class Cause:
    """What is wrong and where (1-based line and column)."""

    message: str
    line: int
    column: int


def _position(text: str, offset: int) -> tuple[int, int]:
    line = text.count("\n", 0, offset) + 1
    return line, offset - (text.rfind("\n", 0, offset) + 1) + 1


def query_form(text: str) -> Cause | None:
    """The query form's cause: an update, or a first word that is no query form (see the module)."""
    tokens = _tokens(text)
    k = 0
    while k < len(tokens) and tokens[k].group().upper() in ("PREFIX", "BASE"):
        k += 1
        while k < len(tokens) and tokens[k].lastgroup != "iri":  # PREFIX name: <iri> / BASE <iri>
            k += 1
        k += 1
    if k >= len(tokens) or not re.fullmatch(r"[A-Za-z]\w*", tokens[k].group()):
        return None
    word = tokens[k].group()
    upper = word.upper()
    line, column = _position(text, tokens[k].start())
    if upper in FORMS:
        return None
    if upper in UPDATES:
        return Cause(f"{word} is SPARQL Update: updates are not allowed, queries are read-only "
                     f"(SELECT, CONSTRUCT, ASK or DESCRIBE)", line, column)
    close = difflib.get_close_matches(upper, FORMS + UPDATES, n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]}?" if close and close[0] in FORMS else ""
    return Cause(f"expected SELECT, CONSTRUCT, ASK or DESCRIBE, found {word!r}{hint}", line, column)


def unbalanced(text: str) -> Cause | None:
    """A string not closed on its line, or the first bracket closed without being opened, or the
    last one never closed."""
    stack: list[tuple[str, int]] = []
    for m in _LEX.finditer(text):
        kind, token = m.lastgroup, m.group()
        if kind == "open_string":
            return Cause(f"the string opened here with {token} is not closed on its line", *_position(text, m.start()))
        if kind != "bracket":
            continue
        if token in "({[":
            stack.append((token, m.start()))
        elif not stack or stack[-1][0] != _PAIRS[token]:
            opened = f" (the {stack[-1][0]!r} at {':'.join(map(str, _position(text, stack[-1][1])))} is still open)" \
                if stack else ""
            return Cause(f"{token!r} closes nothing{opened}", *_position(text, m.start()))
        else:
            stack.pop()
    if stack:
        token, start = stack[-1]
        closer = next(c for c, o in _PAIRS.items() if o == token)
        return Cause(f"the {token!r} opened here is never closed (a {closer!r} is missing)", *_position(text, start))
    return None


def stray_word(text: str) -> Cause | None:
    """A bare word that is no SPARQL keyword or function (``LIMT``, ``FILTR``), or a ``?`` without a
    name: the parser reports such a word wherever it gave up, often at the end of the query."""
    for m in _tokens(text):
        word = m.group()
        if m.lastgroup == "run" and word in ("?", "$"):
            return Cause(f"{word} without a name: a variable is ?name", *_position(text, m.start()))
        if m.lastgroup == "run" and re.fullmatch(r"[A-Za-z][\w-]*", word) and word.upper() not in _WORDS:
            close = difflib.get_close_matches(word.upper(), sorted(_WORDS - {"A", "TRUE", "FALSE"}), n=1, cutoff=0.7)
            hint = f"; did you mean {close[0]}?" if close else " (a prefixed name needs its ':')"
            return Cause(f"{word!r} is no SPARQL keyword or function{hint}", *_position(text, m.start()))
    return None


def incomplete_triple(text: str) -> Cause | None:
    """A ``.`` or ``}`` after too few terms for a triple pattern: 3 after ``{`` or ``.``, 2 after ``;``
    and 1 after ``,`` (``{ ?x ?p }``). Patterns after FILTER, VALUES, ... are not checked."""
    terms, since, checked = 0, "{", True
    for m in _tokens(text):
        token, kind = m.group(), m.lastgroup
        if token in ("{", "}", ".", ";", ","):
            if token in ("}", ".") and checked and 0 < terms < _NEEDED[since]:
                return Cause(f"{token!r} ends an incomplete triple pattern (a subject, a predicate and an object "
                             "are needed)", *_position(text, m.start()))
            terms, since = 0, ("{" if token == "}" else token)
            checked = checked or token in ("{", "}", ".")
        elif kind == "run" and token.upper() in _NOT_TRIPLES:
            checked = False
        elif kind in ("run", "iri", "string") or token in (")", "]"):
            terms += 1
    return None


def _found(text: str, line: int, column: int) -> str:
    """What stands at the parser's position: a word, a character or the end of the query."""
    lines = text.splitlines()
    rest = lines[line - 1][column - 1:] if 0 < line <= len(lines) else ""
    rest = rest.lstrip()
    if not rest:
        return "end of line" if line < len(lines) else "end of query"
    m = re.match(r"[\w:?$-]+|\S", rest)
    return repr(m.group()) if m else repr(rest[0])


def expected(message: str) -> list[str]:
    """The tokens of Oxigraph's "expected one of ..." that a reader can act on."""
    listed = message.removeprefix("expected one of ").removeprefix("expected ")
    if listed == message:
        return []
    words = [w.strip() for w in re.split(r",\s*(?=[^,]*(?:$|,))", listed.replace("\n", " "))]
    return [w for w in words if w and w not in _NOISE and not w.startswith(("[", "|", "'"))]


def explain(text: str, line: int, column: int, message: str) -> Cause:
    """The cause of the syntax error Oxigraph reported at ``line``:``column`` with ``message``."""
    if "Prefix not found" in message:
        return Cause(message, line, column)
    cause = query_form(text) or unbalanced(text) or stray_word(text) or incomplete_triple(text)
    if cause is not None:
        return cause
    tokens = expected(message)
    found = _found(text, line, column)
    if not tokens:
        return Cause(f"unexpected {found}", line, column)
    if len(tokens) > 6:  # a list of function names: the parser wanted an expression
        return Cause(f"unexpected {found}: expected an expression (a variable, a value or a function call)",
                     line, column)
    listed = " or ".join(tokens) if len(tokens) < 3 else "one of " + ", ".join(tokens)
    return Cause(f"unexpected {found}; expected {listed}", line, column)
