"""Generators: one small class per target over one resolved model.

Each has ``outputs() -> dict[relative_path, text]``; :mod:`stepnc_graph.artefacts.build`
writes them. Output is byte-stable: sorted, no timestamps, no random blank
node labels.
"""
