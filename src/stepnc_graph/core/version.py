"""The version of stepnc-graph (as ``pyproject.toml`` gives it), at the bottom of the layers: the
loaders write it into each load's provenance, the CLI prints it."""

__version__ = "0.1.0"
