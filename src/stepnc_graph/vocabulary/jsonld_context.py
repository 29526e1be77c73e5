"""The shipped JSON-LD context (``ontology/context.jsonld``, written by
:mod:`stepnc_graph.generators.context`) read as term definitions: what the JSON-LD export compacts
with (:mod:`stepnc_graph.exporting.jsonld`) and the import serves for the context's IRI
(:mod:`stepnc_graph.loading.jsonld`)."""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

from stepnc_graph.core.resources import ontology_dir


@dataclass(frozen=True)
class TermDef:
    """What a key means: its property IRI, ``@type`` coercion and container; ``items``: IRI -> item term."""

    iri: str
    type: str | None = None
    container: str | None = None
    items: dict[str, str] = field(default_factory=dict, compare=False)


#: a key without a term definition (a compact or absolute IRI): values carry their own types
PLAIN = TermDef("")


class Context:
    """The shipped context, read as term definitions for the compaction."""

    def __init__(self, document: dict[str, Any]) -> None:
        self.source: dict[str, Any] = document["@context"]
        self.prefixes = {k: v for k, v in self.source.items() if isinstance(v, str) and v.endswith(("#", "/"))
                         and not k.startswith("@")}
        #: class IRI -> its term; class term -> its scoped term definitions (key -> TermDef)
        self.class_terms: dict[str, str] = {}
        self.scoped: dict[str, dict[str, TermDef]] = {}
        for key, value in self.source.items():
            if key.startswith("@") or key in self.prefixes:
                continue
            iri = self.expand(value if isinstance(value, str) else value["@id"])
            self.class_terms[iri] = key
            scoped = value.get("@context", {}) if isinstance(value, dict) else {}
            self.scoped[key] = {name: self.term(d) for name, d in scoped.items()}

    def expand(self, value: str) -> str:
        prefix, _, rest = value.partition(":")
        return self.prefixes[prefix] + rest if prefix in self.prefixes else value

    def term(self, definition: str | dict[str, Any]) -> TermDef:
        if isinstance(definition, str):
            return TermDef(self.expand(definition))
        kind = definition.get("@type")
        items = {self.expand(iri): name for name, iri in definition.get("@context", {}).items()}
        return TermDef(self.expand(definition["@id"]), self.expand(kind) if kind and kind[0] != "@" else kind,
                       definition.get("@container"), items)

    def compact(self, iri: str) -> str:
        """``prefix:rest`` for an IRI under a prefix, else the IRI."""
        best = ""
        for name, ns in self.prefixes.items():
            if iri.startswith(ns) and len(iri) > len(ns) and not iri[len(ns):].startswith("//") \
                    and len(ns) > len(self.prefixes.get(best, "")):
                best = name
        return f"{best}:{iri[len(self.prefixes[best]):]}" if best else iri

    def subset(self, class_terms: Iterable[str]) -> dict[str, Any]:
        """The context restricted to the prefixes and the given class terms (what a document uses)."""
        wanted = set(class_terms)
        return {k: v for k, v in self.source.items() if k.startswith("@") or k in self.prefixes or k in wanted}


@lru_cache(maxsize=1)
def shipped_context() -> Context:
    """``ontology/context.jsonld``, read once."""
    return Context(json.loads(context_text()))


@lru_cache(maxsize=1)
def context_text() -> str:
    return (ontology_dir() / "context.jsonld").read_text(encoding="utf-8")
