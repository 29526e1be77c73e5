"""Exporting a store's graphs: RDF serialisations, JSON-LD with the shipped context, Part 21."""
