"""What a JSON-LD processor would drop, found and located (:mod:`stepnc_graph.loading.jsonld`).

The document is read twice by the processor, as JSON-LD says and leniently (invalid IRIs kept);
where the two differ, these functions name each invalid value and its JSON pointer, and say why
the value is no IRI. Also the graph a document names (:func:`named_graph_of`).
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from typing import Any

import pyoxigraph as ox

from stepnc_graph.core.naming import CONTEXT_IRI
from stepnc_graph.loading.jsonld_read import (JsonLdError, BAD_PERCENT, BLANK_LABEL, NOT_IN_IRI, JsonPath, SCHEME,
                                              char_name, printable, quote, show_pointer, pointer, read_bytes)


#: how many invalid values one message names
SHOWN = 5


def invalid_terms(quads: list[ox.Quad]) -> tuple[dict[str, str], set[str]]:
    """The invalid terms of leniently read quads (up to :data:`SHOWN` and one): text -> why; and
    the blank node labels N-Triples cannot write (JSON-LD allows any text after ``_:``)."""
    valid: set[str] = set()
    problems: dict[str, str] = {}
    odd: set[str] = set()
    for q in quads:
        for term in (q.subject, q.predicate, q.object, q.graph_name):
            if isinstance(term, ox.Literal):
                key = "\x00" + term.datatype.value + "@" + (term.language or "")  # no IRI holds a NUL
            elif isinstance(term, ox.NamedNode):
                key = term.value
            elif isinstance(term, ox.BlankNode):
                if not BLANK_LABEL.fullmatch(term.value):
                    odd.add(term.value)
                continue
            else:
                continue
            if key in valid:
                continue
            found = _invalid(term)
            if not found:
                valid.add(key)
            problems.update((text, why) for text, why in found if text not in problems)
        if len(problems) > SHOWN:
            break
    return problems, odd


def relabelled(quads: list[ox.Quad], odd: set[str]) -> list[ox.Quad]:
    """``quads`` with each blank node whose label N-Triples cannot write given another (labels
    only tell blank nodes apart within the document: nothing is lost)."""
    labels = {label: ox.BlankNode("u" + hashlib.sha256(label.encode("utf-8", "surrogatepass")).hexdigest()[:32])
              for label in odd}

    def term(t: Any) -> Any:
        return labels.get(t.value, t) if isinstance(t, ox.BlankNode) else t

    return [ox.Quad(term(q.subject), q.predicate, term(q.object), q.graph_name) if isinstance(q.subject, ox.BlankNode)
            or isinstance(q.object, ox.BlankNode) else q for q in quads]


def masked(lenient: list[ox.Quad], strict: list[ox.Quad]) -> dict[str, str]:
    """The IRIs lenient resolution made out of invalid references: in no statement JSON-LD keeps."""
    kept = {t for q in strict for t in (q.subject, q.predicate, q.object, q.graph_name)}
    problems: dict[str, str] = {}
    for q in lenient:
        culprit = next((t for t in (q.subject, q.object, q.predicate, q.graph_name)
                        if isinstance(t, ox.NamedNode) and t not in kept), None)
        if culprit is not None:
            problems.setdefault(culprit.value, _MASKED)
    return problems or {"(a statement)": "what JSON-LD reads: a reference in the document is no valid IRI reference"}


def processor_error(doc: Any, message: str, name: str) -> JsonLdError:
    """The processor's complaint, without its positions (they are of the document as re-written
    here) and located in the document when it quotes a value of it."""
    message = re.sub(r"^Parser error at line \d+[^:]*: ", "", message)
    message = re.sub(r" \(line \d+\)$", "", message)
    if "LoadDocumentCallback" in message:
        return JsonLdError("names a context by its IRI; stepnc-graph never fetches contexts: put the context in "
                           f"the document, or name the shipped one, {CONTEXT_IRI}", name)
    for quoted in re.findall(r"'(.+)'", message, re.DOTALL) + re.findall(r"'(.+?)'", message, re.DOTALL):
        where = path_of(locate(doc, quoted))
        if where is None:
            continue
        if "must be an IRI" in message and iri_problem(quoted):
            [(_, why)] = iri_problem(quoted)
            return JsonLdError(f"{quote(quoted)} is not {why}", name, pointer=pointer(where))
        return JsonLdError(f"not JSON-LD that can be read: {printable(message)}", name, pointer=pointer(where))
    return JsonLdError(f"not JSON-LD that can be read: {printable(message)}", name)


def dropped_error(doc: Any, problems: dict[str, str], name: str) -> JsonLdError:
    """The error for a document JSON-LD would read only by dropping statements: its invalid values."""
    found = [_as_written(value, locate(doc, value)) if why is _MASKED else (value, why, path_of(locate(doc, value)))
             for value, why in list(problems.items())[:SHOWN]]
    first = found[0][2] if found else None
    if len(found) == 1:
        value, why, _ = found[0]
        return JsonLdError(f"{quote(value)} is not {why}; JSON-LD would drop it, and what it says would be lost",
                           name, pointer=pointer(first) if first is not None else None)
    shown = "; ".join(f"{quote(value)}" + (f" at {show_pointer(pointer(where))}" if where is not None else "")
                      + f" is not {why}" for value, why, where in found)
    return JsonLdError(f"holds {'more than ' if len(problems) > SHOWN else ''}{len(found)} values JSON-LD would "
                       f"drop, and what they say would be lost: {shown}", name,
                       pointer=pointer(first) if first is not None else None)


_MASKED = "what the document says: a reference that is no valid IRI reference was resolved to it"


def _as_written(iri: str, found: tuple[JsonPath, str] | None) -> tuple[str, str, JsonPath | None]:
    """An IRI that only lenient resolution made (``"a b/../c"`` -> ``.../c``) as the document writes it."""
    if found is None:
        return iri, _MASKED, None
    where, text = found
    return text, "a valid IRI reference: " + iri_reason(text, "not one"), where


def _invalid(term: Any) -> list[tuple[str, str]]:
    """What is wrong with one term of a leniently read quad: (its text, why) for each invalid part."""
    out: list[tuple[str, str]] = []
    if isinstance(term, ox.NamedNode):
        out += iri_problem(term.value)
    elif isinstance(term, ox.Literal):
        out += iri_problem(term.datatype.value)
        if term.language is not None:
            try:
                ox.Literal(term.value, language=term.language)
            except ValueError:
                out.append((term.language, "a language tag (BCP 47, such as en or de-CH)"))
    return out


def iri_problem(iri: str) -> list[tuple[str, str]]:
    """``[(iri, why it is not one)]``, or ``[]`` for a valid IRI."""
    try:
        ox.NamedNode(iri)
    except ValueError as e:
        return [(iri, "an IRI: " + iri_reason(iri, str(e)))]
    return []


def iri_reason(iri: str, error: str) -> str:
    """Why ``iri`` is not an IRI, in the terms of RFC 3987."""
    bad = NOT_IN_IRI.search(iri)
    if bad:
        return f"it holds {char_name(bad.group())}, which no IRI may hold"
    if BAD_PERCENT.search(iri):
        return "it holds a '%' that is not followed by two hexadecimal digits"
    if not SCHEME.match(iri):
        head = re.match(r"[^/?#]*:", iri)
        if head:
            return (f"{quote(head.group()[:-1])} is no scheme (a scheme is a letter, then letters, digits, '+', "
                    "'-' or '.')")
        return ("it is relative, with no scheme and no base to resolve it against: a key the context does not "
                'define, or a reference where "@base" is null')
    return printable(error)


def _ends_with(iri: str, text: str) -> bool:
    """Whether ``iri`` ends with ``text`` after a delimiter: how a relative reference or the local
    part of a compact IRI is found in what it became."""
    return bool(text) and len(iri) > len(text) and iri.endswith(text) and iri[-len(text) - 1] in "/#:?"


def path_of(found: tuple[JsonPath, str] | None) -> JsonPath | None:
    return found[0] if found is not None else None


def locate(doc: Any, value: str, exact: bool = False) -> tuple[JsonPath, str] | None:
    """Where ``value`` (an IRI as the processor made it, a blank node, a language tag) is written
    in the document: a key or string equal to it, else the longest one it ends with (a relative
    reference or a compact IRI, resolved), else a reference with dot segments ending as it does;
    outside contexts first. Its path and the text written there."""
    best: tuple[tuple[int, int, int], JsonPath, str] | None = None
    last = value.rsplit("/", 1)[-1]
    stack: list[tuple[Any, JsonPath, bool]] = [(doc, None, False)]
    while stack:
        item, path, in_context = stack.pop()
        candidates: list[tuple[str, JsonPath]] = []
        if isinstance(item, dict):
            for key, v in item.items():
                candidates.append((key, (path, key)))
                stack.append((v, (path, key), in_context or key == "@context"))
        elif isinstance(item, list):
            stack.extend((v, (path, i), in_context) for i, v in enumerate(item))
        elif isinstance(item, str):
            candidates.append((item, path))
        for text, where in candidates:
            if exact:
                rank = 4 if text == value else 0
            else:
                local = text.partition(":")[2]
                rank = (4 if text == value else 3 if _ends_with(value, text) else 2 if _ends_with(value, local) else
                        1 if last and text.endswith("/" + last) and ("/../" in text or "/./" in text) else 0)
            if rank:
                score = (int(not in_context), rank, len(text))
                if best is None or score > best[0]:
                    best = (score, where, text)
    return (best[1], best[2]) if best is not None else None


def named_graph_of(path: Path) -> str | None:
    """The graph a JSON-LD file names, if it is readable and names one: what it is loaded as
    without ``--base-iri``. That is the top-level ``@id`` of a graph's export, or the ``@id`` of
    the one named graph of a whole-store export; relative to ``@base``. Errors are left to the load."""
    try:
        doc = json.loads(read_bytes(path).decode("utf-8-sig"))
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(doc, dict):
        return None
    bases = _bases(doc)
    if not isinstance(doc.get("@id"), str):
        inner = doc.get("@graph")
        if not (isinstance(inner, list) and len(inner) == 1 and isinstance(inner[0], dict)):
            return None
        doc = inner[0]
        bases += _bases(doc)
    if not isinstance(doc.get("@id"), str) or "@graph" not in doc:
        return None
    from urllib.parse import urljoin

    try:  # urljoin raises ValueError too ("Invalid IPv6 URL" for a '[' in the authority)
        iri = urljoin(bases[-1], doc["@id"]) if bases else str(doc["@id"])
        ox.NamedNode(iri)
    except ValueError:
        return None
    return iri


def _bases(node: dict[str, Any]) -> list[str]:
    """The ``@base`` values of a node's own (inline) contexts, in order."""
    contexts = node.get("@context")
    return [c["@base"] for c in (contexts if isinstance(contexts, list) else [contexts])
            if isinstance(c, dict) and isinstance(c.get("@base"), str)]
