"""The bottom layer: errors, the IRIs the project mints, where its data files are, SPARQL text checks.

Nothing here imports another part of stepnc-graph."""
