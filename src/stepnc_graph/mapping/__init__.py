"""Part 21 instances -> RDF, driven by the resolved schema model (and back, in the writer)."""
