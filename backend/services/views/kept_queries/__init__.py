"""Queries kept as rows, current with each applied journal step: a report's rows are its query's answer, kept by
re-running the query for just the keys each step's new triples can change."""
