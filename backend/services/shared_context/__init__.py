"""Shared context: one canonical URI per real-world event that several robots observe."""
