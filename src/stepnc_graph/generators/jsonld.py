"""``ontology/context.jsonld``: the JSON-LD context for exported graphs.

Prefixes only (``stepnc:``, ``p21:``, ...): compact and robust, since the
vocabulary's dotted attribute names read well as ``stepnc:outer_diameter.its_id``.
"""

from __future__ import annotations

import json

from stepnc_graph.naming import P21_NS, Naming

PREFIXES = {
    "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#",
    "rdfs": "http://www.w3.org/2000/01/rdf-schema#",
    "owl": "http://www.w3.org/2002/07/owl#",
    "xsd": "http://www.w3.org/2001/XMLSchema#",
    "dcterms": "http://purl.org/dc/terms/",
    "prov": "http://www.w3.org/ns/prov#",
}


def context(naming: Naming) -> dict[str, str]:
    return {"stepnc": naming.namespace, "p21": P21_NS, **PREFIXES}


class JsonLdContextGenerator:
    def __init__(self, naming: Naming) -> None:
        self.n = naming

    def outputs(self) -> dict[str, str]:
        return {"context.jsonld": json.dumps({"@context": context(self.n)}, indent=2, sort_keys=True) + "\n"}
