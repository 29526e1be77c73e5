"""SPARQL that would make stepnc-graph reach out to the network: refused unless asked for.

A SPARQL 1.1 Federated Query ``SERVICE`` clause makes the engine that runs it
send the inner pattern to whatever URL the clause names, and ``LOAD <url>`` in
an update makes it fetch one -- from the machine running stepnc-graph, with that
machine's place in the network (an intranet service, a cloud metadata address,
something listening on loopback). A query from a web page, a shapes file or a
colleague must not do that unasked, so every SPARQL text stepnc-graph runs for a
user (``query``, the SPARQL of ``validate``'s shapes, what ``serve`` forwards)
goes through :func:`refuse_outbound` first. Neither pyoxigraph's ``Store.query``
nor Oxigraph's server has a switch that turns ``SERVICE`` off (both are built
with an HTTP client), so this check is the only layer.

How: the text is parsed by rdflib's SPARQL 1.1 parser and its parse tree is
searched for a ``ServiceGraphPattern`` (and, in an update, a ``Load``): case,
comments, strings, IRIs and names such as ``ex:service`` cannot hide the
keyword or fake it. That parser takes about 0.1 s per query, and 0.2 s to
import -- as much as a whole query over a small program -- so it runs only when
the text can hold the keyword at all: with SPARQL's codepoint escapes (``\\u``,
``\\U``) expanded and case folded, the keyword's letters must stand in a row. No
library query holds them. A text that holds them and that the parser cannot
read (a syntax error, or syntax beyond SPARQL 1.1) is refused as well: nothing
shows it to be harmless.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

from stepnc_graph.core.errors import StepncGraphError

#: what --allow-service allows, for messages
OPT_IN = "--allow-service"
_ESCAPE = re.compile(r"\\u([0-9A-Fa-f]{4})|\\U([0-9A-Fa-f]{8})")
#: parse-tree nodes that send a request: SERVICE anywhere, LOAD in an update
_OUTBOUND = {"ServiceGraphPattern": "SERVICE", "Load": "LOAD"}


class OutboundRefused(StepncGraphError, ValueError):
    """SPARQL that would send a request to another server (``SERVICE``, ``LOAD``), refused.

    ``keyword`` is what was found (``SERVICE`` or ``LOAD``); ``str()`` is the
    whole message, saying why and how to allow it.
    """

    def __init__(self, keyword: str, detail: str = "") -> None:
        self.keyword = keyword
        reason = (f"{keyword} is refused: it makes stepnc-graph send a request to another server, which a "
                  "query from a file, a shapes graph or a web page must not do unasked")
        super().__init__(reason + (f" ({detail})" if detail else ""))


def _unescaped(text: str) -> str:
    """``text`` with SPARQL's codepoint escapes expanded (SPARQL 1.1 Query, 19.2: a parser may
    expand them anywhere before it reads the text)."""
    def char(match: re.Match[str]) -> str:
        code = int(match.group(1) or match.group(2), 16)
        return chr(code) if code <= 0x10FFFF else match.group(0)

    return _ESCAPE.sub(char, text)


def _may_hold(text: str, words: tuple[str, ...]) -> bool:
    """Whether ``words`` (lower case) can occur in ``text`` as keywords: their letters in a row,
    whatever their case and escapes."""
    folded = _unescaped(text).casefold()
    return any(word in folded for word in words)


def _node_names(node: Any) -> Iterator[str]:
    """The names of every rdflib parse-tree node (``CompValue``) under ``node``."""
    from pyparsing import ParseResults
    from rdflib.plugins.sparql.parserutils import CompValue

    stack = [node]
    while stack:
        item = stack.pop()
        if isinstance(item, CompValue):
            yield item.name
            stack.extend(item.values())
        elif isinstance(item, (list, tuple, ParseResults)):
            stack.extend(item)
        elif isinstance(item, dict):
            stack.extend(item.values())


def outbound_keyword(text: str, *, update: bool = False) -> tuple[str, str] | None:
    """The outbound operation (``SERVICE``, or ``LOAD`` in an ``update``) that the SPARQL text uses,
    with a note on how it was found; None when it uses none."""
    words = ("service", "load") if update else ("service",)
    if not _may_hold(text, words):
        return None
    from pyparsing import ParseBaseException
    from rdflib.plugins.sparql.parser import parseQuery, parseUpdate

    try:
        tree = parseUpdate(text) if update else parseQuery(text)
    except (ParseBaseException, ValueError, TypeError, RecursionError) as exc:
        keyword = "SERVICE" if "service" in _unescaped(text).casefold() else "LOAD"
        where = (f" at line {exc.lineno}, column {exc.col}" if isinstance(exc, ParseBaseException) else "")
        return keyword, (f"the text mentions {keyword} and a SPARQL 1.1 parser cannot read it{where}, so it "
                         f"cannot be shown not to call it")
    found = {_OUTBOUND[name] for name in _node_names(tree) if name in _OUTBOUND}
    if not found:
        return None
    return ("SERVICE" if "SERVICE" in found else "LOAD"), ""


def refuse_outbound(text: str, *, update: bool = False, allow: bool = False, opt_in: str = OPT_IN) -> None:
    """Raise :class:`OutboundRefused` if the SPARQL ``text`` (a query, or an ``update``) would send a
    request to another server, unless ``allow``; ``opt_in`` names the option that allows it."""
    if allow:
        return
    found = outbound_keyword(text, update=update)
    if found is not None:
        keyword, note = found
        raise OutboundRefused(keyword, "; ".join(filter(None, (note, f"{opt_in} allows it"))))
