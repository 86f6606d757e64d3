"""SEGB server: receives robots' semantic logs, stores them in a triple store, serves audits."""

__version__ = "0.1.0"
