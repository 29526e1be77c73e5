"""Harnesses for tests and benchmarks: random programs, damaged inputs (fuzzing)."""
