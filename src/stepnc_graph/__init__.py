"""stepnc-graph: ISO 14649 (STEP-NC) process data as a knowledge graph."""

__version__ = "0.1.0"
