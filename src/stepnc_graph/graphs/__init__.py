"""Graphs of a store and what they are: programs, derived layers, link graphs, the vocabulary graph
(above the store, which only keeps named graphs)."""
