"""The walk over a JSON-LD document before the processor sees it (:mod:`stepnc_graph.loading.jsonld`):
the shipped context put where its IRI is named, any other context IRI refused with its JSON pointer
(no network, no files, ever), and keys and values a processor would silently drop refused.
"""

from __future__ import annotations

import json
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.naming import CONTEXT_IRI
from stepnc_graph.loading.jsonld_problems import iri_problem, iri_reason
from stepnc_graph.loading.jsonld_read import (JsonLdError, KEYWORDS, MAX_DEPTH, MAX_IRI, BAD_PERCENT, KEYWORD_FORM,
                                              NOT_IN_IRI, JsonPath, Refused, SCHEME, quote, too_deep, pointer)


def _fetched(iri: str, path: JsonPath, name: str) -> JsonLdError:
    return JsonLdError(f"names the context {quote(iri)} by its IRI; stepnc-graph never fetches contexts (a "
                       "document could make it connect anywhere, read local files or change what its terms "
                       f"mean): put the context in the document, or name the shipped one, {CONTEXT_IRI}",
                       name, pointer=pointer(path))


def _first_string(value: Any, path: JsonPath) -> tuple[str, JsonPath] | None:
    """The first string inside nested arrays, and where it is."""
    stack = [(value, path)]
    while stack:
        item, where = stack.pop()
        if isinstance(item, str):
            return item, where
        if isinstance(item, list):
            stack.extend((v, (where, i)) for i, v in reversed(list(enumerate(item))))
    return None


class _Contexts:
    """Resolves the contexts of one document: the shipped one is put in place (one object, not
    walked again), any other named by IRI is refused.

    The shipped context's IRI (and an ``@import`` of it) is taken in the document's top-level
    ``@context`` only: it stands for some 7,500 JSON values of term definitions, which a
    processor would process again for every node naming it -- a few bytes each, minutes of
    work for a small document. Once, at the top, is all a program needs.
    """

    def __init__(self, name: str) -> None:
        self.name = name
        self.shipped: dict[str, Any] | None = None
        #: the first scoped context that is not the shipped context's (reported after the walk,
        #: so that a context that would be fetched is reported first)
        self.unshipped: JsonLdError | None = None

    def the_shipped(self, path: JsonPath) -> dict[str, Any]:
        if not _at_top(path):
            raise JsonLdError(f"names the shipped context, {CONTEXT_IRI}, below the top of the document; name it "
                              "in the document's top-level @context only (it defines every term of a program, and "
                              "a processor would process all of it again here, for every node)", self.name,
                              pointer=pointer(path))
        if self.shipped is None:
            from stepnc_graph.vocabulary.jsonld_context import shipped_context

            self.shipped = shipped_context().source
        return self.shipped

    def entry(self, value: Any, path: JsonPath) -> Any:
        """One entry of a ``@context`` (the value itself or a member of its array)."""
        if value is None or isinstance(value, dict):
            return value
        if isinstance(value, str):
            if value != CONTEXT_IRI:
                raise _fetched(value, path, self.name)
            return self.the_shipped(path)
        if isinstance(value, list):
            inner = _first_string(value, path)
            if inner is not None and inner[0] != CONTEXT_IRI:
                raise _fetched(inner[0], inner[1], self.name)
            raise JsonLdError("an array inside a @context array: JSON-LD allows objects, null and IRIs there, "
                              "not arrays", self.name, pointer=pointer(path))
        if isinstance(value, Refused):
            raise JsonLdError(value.message, self.name, pointer=pointer(path))
        raise JsonLdError(f"a @context is an object, null, the IRI {CONTEXT_IRI} or an array of these, not "
                          f"{json.dumps(value)}", self.name, pointer=pointer(path))

    def context(self, value: Any, path: JsonPath) -> Any:
        """The value of a ``@context`` key, resolved."""
        if isinstance(value, list):
            return [self.entry(v, (path, i)) for i, v in enumerate(value)]
        return self.entry(value, path)

    def imported(self, context: dict[str, Any], path: JsonPath) -> None:
        """Inline the shipped context where a context ``@import``\\ s it (its own terms win)."""
        value = context["@import"]
        if value != CONTEXT_IRI:
            if isinstance(value, str):
                raise _fetched(value, (path, "@import"), self.name)
            raise JsonLdError(f"@import names one context by its IRI, {CONTEXT_IRI} here, not "
                              f"{quote(json.dumps(value))}", self.name, pointer=pointer((path, "@import")))
        del context["@import"]
        for k, v in self.the_shipped((path, "@import")).items():
            context.setdefault(k, v)

    def check_scoped(self, resolved: Any, path: JsonPath) -> None:
        """A node's (or the document's) context: each term definition in it that has a scoped
        context must be the shipped context's definition of that term.

        A processor processes a scoped context each time a node or value uses it, and every
        term definition with one costs it a copy of the whole active context: a document's
        own scoped contexts could make a small document cost minutes (2,000 such terms in
        one context: 0.5 s, twice as many four times that). The shipped context's are small
        and few, which bounds that work to what a program needs.
        """
        if self.unshipped is not None:
            return
        entries = resolved if isinstance(resolved, list) else [resolved]
        for i, entry in enumerate(entries):
            if not isinstance(entry, dict) or entry is self.shipped:
                continue
            from stepnc_graph.vocabulary.jsonld_context import shipped_context

            shipped = shipped_context().source
            for term, definition in entry.items():
                if isinstance(definition, dict) and "@context" in definition and definition != shipped.get(term):
                    where = ((path, i) if isinstance(resolved, list) else path, term)
                    self.unshipped = JsonLdError(
                        f"the term {quote(term)} has a scoped context (@context) of its own; scoped contexts are "
                        "taken as the shipped context defines them (for this term: "
                        f"{'none' if term not in shipped else 'a different one'}), since a processor processes "
                        "one again for every node that uses it: define the term without @context, or as the "
                        "shipped context does", self.name, pointer=pointer(where))
                    return


def _at_top(path: JsonPath) -> bool:
    """Whether ``path`` is in the document's top-level ``@context`` (its value, a member of its
    array, or the ``@import`` of one of these)."""
    tokens: list[str | int] = []
    while path is not None:
        path, token = path
        tokens.append(token)
    tokens.reverse()
    if tokens[-1:] == ["@import"]:
        tokens.pop()
    return tokens[:1] == ["@context"] and (len(tokens) == 1 or (len(tokens) == 2 and isinstance(tokens[1], int)))


def _check_text(text: str, path: JsonPath, name: str) -> None:
    """A string holding a lone surrogate (``"\\ud800"`` in JSON) is no Unicode text: refused."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        raise JsonLdError("a string holds a lone surrogate (an unpaired \\ud800-\\udfff escape): no Unicode "
                          "text, so no RDF literal or IRI can hold it", name, pointer=pointer(path)) from None


def _check_key(key: str, path: JsonPath, name: str) -> None:
    if not key.isascii():
        _check_text(key, (path, key), name)
    if key[:1] == "@" and key not in KEYWORDS and KEYWORD_FORM.fullmatch(key):
        raise JsonLdError(f"the key {quote(key)} has the form of a keyword but is none; a JSON-LD processor "
                          "ignores it, so its value would be lost: give the key an IRI (or a term the context "
                          "defines)", name, pointer=pointer((path, key)))


def _check_bases(context: dict[str, Any], path: JsonPath, name: str) -> None:
    """A context's ``@base`` and ``@vocab`` must be IRI references: resolving against an invalid
    one could give valid-looking IRIs where JSON-LD has none."""
    for key in ("@base", "@vocab"):
        value = context.get(key)
        if isinstance(value, str) and (NOT_IN_IRI.search(value) or BAD_PERCENT.search(value) or (
                SCHEME.match(value) and iri_problem(value))):
            try:
                ox.NamedNode(value)
                error = "not one"
            except ValueError as e:
                error = str(e)
            raise JsonLdError(f"{quote(value)} is not an IRI reference: {iri_reason(value, error)}", name,
                              pointer=pointer((path, key)))


def _floating(value: dict[str, Any], path: JsonPath) -> bool:
    """Whether ``value`` is a value or list object with no node to belong to: the document itself,
    or a member of a top-level array or of a ``@graph`` array."""
    if not ("@value" in value or "@list" in value):
        return False
    if path is None:
        return True
    parent, token = path
    return isinstance(token, int) and (parent is None or parent[1] == "@graph")


def local_contexts(doc: Any, name: str) -> Any:
    """``doc``, checked all through and with every context named by an IRI resolved without the network.

    The shipped context's IRI, in the document's top-level ``@context``, becomes the
    installed context; any other IRI -- in a ``@context`` anywhere (the document, a node, a
    type- or property-scoped term definition, a nested array) or in ``@import`` -- is
    refused: a JSON-LD processor would fetch it. Refused as well, each with its JSON
    pointer: what the JSON reader marked (a key twice, a number JSON-LD cannot keep), a lone
    surrogate, a key of keyword form that is no keyword, nesting deeper than
    :data:`MAX_DEPTH`, and a scoped context (a term definition's own ``@context``) that is
    not the shipped context's (see :meth:`_Contexts.check_scoped`).
    """
    contexts = _Contexts(name)
    stack: list[tuple[Any, JsonPath, int, bool]] = [(doc, None, 1, False)]
    while stack:
        value, path, depth, in_context = stack.pop()
        kind = type(value)
        if kind is str:
            if not value.isascii():
                _check_text(value, path, name)
            continue
        if kind is Refused:
            raise JsonLdError(value.message, name, pointer=pointer(path))
        if kind is not dict and kind is not list:
            continue
        if depth > MAX_DEPTH:
            raise JsonLdError(too_deep(), name, pointer=pointer(path))
        if kind is list:
            for i, item in enumerate(value):
                if type(item) in (dict, list, Refused) or (type(item) is str and not item.isascii()):
                    stack.append((item, (path, i), depth + 1, in_context))
            continue
        if value is contexts.shipped:  # put in place by this walk: nothing to check in it
            continue
        for key in value:
            _check_key(key, path, name)
        node_id = value.get("@id")
        if type(node_id) is str and len(node_id) > MAX_IRI:
            raise JsonLdError(f"an @id of {len(node_id):,} characters (at most {MAX_IRI:,}): every statement "
                              "about the node would repeat it", name, pointer=pointer((path, "@id")))
        if "@context" in value:
            value["@context"] = contexts.context(value["@context"], (path, "@context"))
            if not in_context:
                contexts.check_scoped(value["@context"], (path, "@context"))
        if "@import" in value:
            contexts.imported(value, path)
        if in_context:
            _check_bases(value, path, name)
        elif _floating(value, path):
            raise JsonLdError("a value on its own, in no node (JSON-LD drops it, and what it says would be "
                              "lost): give it a node and a property", name, pointer=pointer(path))
        stack.extend((item, (path, key), depth + 1, in_context or key == "@context")
                     for key, item in value.items() if item is not contexts.shipped)
    if contexts.unshipped is not None:
        raise contexts.unshipped
    return doc
