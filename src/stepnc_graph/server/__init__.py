"""Serving a store as a SPARQL 1.1 endpoint (Oxigraph's server behind a guard)."""
