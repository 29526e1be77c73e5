"""Querying: the SPARQL query library, parameters as RDF terms, result formats."""
