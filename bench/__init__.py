"""Benchmarks: they print measured numbers; they are not timed tests."""
