"""The workplan of a program as a graph (networkx) and a picture (SVG, PNG)."""
