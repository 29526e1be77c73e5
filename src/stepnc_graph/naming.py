"""Every IRI stepnc-graph mints is minted here.

Scheme (documented in ``ontology/README.md``, stable for good):

* vocabulary terms live in one namespace, ``.../iso14649#``, whatever schema
  declares them (names are unique across the model, and analysts should not
  need to know which part of ISO 14649 a term comes from to write a query);
* a local name is the EXPRESS name in lower case: ``stepnc:outer_diameter``;
* members are scoped by their owner with a dot: the attribute ``its_id`` of
  ``machining_operation`` is ``stepnc:machining_operation.its_id``; the
  enumeration item ``tcp`` of ``feedrate_reference`` is
  ``stepnc:feedrate_reference.tcp`` (entity/type names never contain dots, so
  the two cannot collide);
* each schema is an ontology ``.../iso14649/<schema_name>``;
* Part 21 structure (ids, lines, unset list members, ...) uses the ``p21:``
  vocabulary of :mod:`stepnc_graph.p21vocab`;
* a loaded file is one named graph; its IRI is the *base IRI* (by default
  ``.../data/<file name>``, or ``--base-iri``) and the instance ``#12`` of it is
  ``<base IRI>/i12`` (``<base IRI>i12`` when the base ends in ``/`` or ``#``):
  the same file content and base IRI always give the same IRIs;
* stepnc-graph's own terms for querying live outside the ISO namespace: one
  generic property per EXPRESS attribute name, ``.../attribute#its_id``
  (prefix ``attr:``; every ``stepnc:<entity>.its_id`` is a sub-property of
  it), and the analysis vocabulary ``.../analysis#`` (prefix ``sga:``) for
  what the standard leaves implicit (roughing and finishing operations, the
  execution order); a file's derived layer is the graph ``<base IRI>/derived``
  and its execution steps are ``<base IRI>/derived/step<n>``;
* an instance with an ``its_id`` label that no other instance of the same
  scope shares also gets an alias ``<base IRI>/id/<scope>/<its_id>``
  (percent-encoded; the scope is the entity declaring ``its_id``, such as
  ``executable`` or ``manufacturing_feature``), ``owl:sameAs`` the instance:
  a link for PLM systems that survives renumbering of the instance ids;
* the links a mapping file attaches to a program's instances live in their own
  named graph ``<base IRI>/links/<mapping file name>`` (percent-encoded).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import PurePath
from typing import TYPE_CHECKING, Any
from urllib.parse import quote

if TYPE_CHECKING:
    from rdflib import Namespace, URIRef

STEPNC_NS = "https://w3id.org/stepnc-graph/iso14649#"
ONTOLOGY_BASE = "https://w3id.org/stepnc-graph/iso14649/"
P21_NS = "https://w3id.org/stepnc-graph/p21#"
P21_ONTOLOGY = "https://w3id.org/stepnc-graph/p21"

#: Generic attribute properties, one per EXPRESS attribute name (prefix ``attr:``).
ATTRIBUTE_NS = "https://w3id.org/stepnc-graph/attribute#"
ATTRIBUTE_ONTOLOGY = "https://w3id.org/stepnc-graph/attribute"
#: The analysis vocabulary: terms for what ISO 14649 leaves implicit (prefix ``sga:``).
ANALYSIS_NS = "https://w3id.org/stepnc-graph/analysis#"
ANALYSIS_ONTOLOGY = "https://w3id.org/stepnc-graph/analysis"

DATA_BASE = "https://w3id.org/stepnc-graph/data/"
#: The named graph holding the vocabulary (ontology/*.ttl) in a store.
VOCABULARY_GRAPH = "https://w3id.org/stepnc-graph/iso14649"
TOOL_IRI = "https://w3id.org/stepnc-graph/tool/"
#: The IRI documents use to name the shipped JSON-LD context (``ontology/context.jsonld``).
#: stepnc-graph never fetches it: its reader serves it from the installed file.
CONTEXT_IRI = "https://w3id.org/stepnc-graph/context.jsonld"

#: ``STEPNC`` and ``P21`` are rdflib Namespaces over the two namespaces above,
#: made on first use (module ``__getattr__``): rdflib costs about 0.1 s to
#: import, and loading a program never needs it.
_NAMESPACES = {"STEPNC": STEPNC_NS, "P21": P21_NS, "ATTR": ATTRIBUTE_NS, "SGA": ANALYSIS_NS}

if TYPE_CHECKING:
    STEPNC: Namespace
    P21: Namespace
    ATTR: Namespace
    SGA: Namespace


def __getattr__(name: str) -> Any:
    if name in _NAMESPACES:
        from rdflib import Namespace

        value = Namespace(_NAMESPACES[name])
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _uri(value: str) -> URIRef:
    """An rdflib IRI; rdflib is imported here, on first use, not with this module."""
    from rdflib import URIRef

    return URIRef(value)


@dataclass(frozen=True)
class Naming:
    """IRI minting for one vocabulary namespace (the shipped one by default)."""

    namespace: str = STEPNC_NS
    ontology_base: str = ONTOLOGY_BASE

    def declaration(self, name: str) -> URIRef:
        """An entity, defined type, enumeration or select."""
        return _uri(self.declaration_iri(name))

    def declaration_iri(self, name: str) -> str:
        """:meth:`declaration` as a plain string (no rdflib: for code on a load's path)."""
        return self.namespace + name.lower()

    def attribute(self, entity: str, attribute: str) -> URIRef:
        return _uri(self.attribute_iri(entity, attribute))

    def attribute_iri(self, entity: str, attribute: str) -> str:
        """:meth:`attribute` as a plain string (no rdflib)."""
        return f"{self.namespace}{entity.lower()}.{attribute.lower()}"

    def enum_item(self, enumeration: str, item: str) -> URIRef:
        return _uri(f"{self.namespace}{enumeration.lower()}.{item.lower()}")

    def ontology(self, schema: str) -> URIRef:
        return _uri(self.ontology_base + schema.lower())

    def ontology_version(self, schema: str, version: str) -> URIRef:
        return _uri(f"{self.ontology_base}{schema.lower()}/{version}")

    def local_name(self, iri: str) -> str | None:
        """The local part of a vocabulary IRI, or None for a foreign IRI."""
        return iri[len(self.namespace):] if iri.startswith(self.namespace) else None


def default_graph_iri(path: str) -> str:
    """The graph IRI of a file loaded without ``--base-iri``: from its file name."""
    return DATA_BASE + quote(PurePath(path).name, safe="")


def instance_prefix(graph_iri: str) -> str:
    """What instance ids are appended to, for a graph IRI."""
    return graph_iri if graph_iri.endswith(("/", "#")) else graph_iri + "/"


def instance_iri(graph_iri: str, p21_id: int) -> str:
    return f"{instance_prefix(graph_iri)}i{p21_id}"


def instance_id(graph_iri: str, iri: str) -> int | None:
    """The #id of an instance IRI of ``graph_iri`` (the inverse of :func:`instance_iri`), else None."""
    head = instance_prefix(graph_iri) + "i"
    digits = iri[len(head):] if iri.startswith(head) else ""
    return int(digits) if digits.isdigit() and digits.isascii() else None


def derived_graph_iri(graph_iri: str) -> str:
    """The named graph that holds the derived (query) layer of a loaded file's graph.

    It lives beside the lossless program graph, is written in the same atomic
    load and removed with it, and the Part 21 writer never reads it.
    """
    return f"{instance_prefix(graph_iri)}derived"


def generic_attribute(name: str) -> URIRef:
    """The generic property of every attribute called ``name``, whatever entity declares it."""
    return _uri(generic_attribute_iri(name))


def generic_attribute_iri(name: str) -> str:
    """:func:`generic_attribute` as a plain string (no rdflib)."""
    return ATTRIBUTE_NS + name.lower()


def analysis_term(name: str) -> URIRef:
    """A term of the analysis vocabulary (``sga:RoughingOperation``, ``sga:next``, ...)."""
    return _uri(ANALYSIS_NS + name)


def execution_step_iri(graph_iri: str, index: int) -> str:
    """The ``index``-th (1-based) step of a file's flattened execution order, in its derived layer."""
    return f"{derived_graph_iri(graph_iri)}/step{index}"


def class_count_iri(graph_iri: str, index: int) -> str:
    """The ``index``-th (1-based) count of instances per class of a file, in its derived layer."""
    return f"{derived_graph_iri(graph_iri)}/count{index}"


def section_iri(graph_iri: str, index: int) -> str:
    """The ``index``-th (1-based) DATA section of a file that has several."""
    return f"{instance_prefix(graph_iri)}section{index}"


def link_graph_iri(graph_iri: str, mapping: str) -> str:
    """The named graph of the links one mapping file (``mapping``: its file name) attaches to a program."""
    return f"{link_graphs_prefix(graph_iri)}{quote(mapping, safe='')}"


def link_graphs_prefix(graph_iri: str) -> str:
    """What every link graph of a program starts with (see :func:`link_graph_iri`)."""
    return f"{instance_prefix(graph_iri)}links/"


def alias_iri(graph_iri: str, scope: str, label: str) -> str:
    """The alias of the one instance of ``scope`` whose its_id is ``label``."""
    return f"{instance_prefix(graph_iri)}id/{scope.lower()}/{quote(label, safe='')}"
