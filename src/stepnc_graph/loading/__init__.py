"""Loading: which inputs become which graphs, Part 21 and JSON-LD programs, the derived layer, PLM links."""
