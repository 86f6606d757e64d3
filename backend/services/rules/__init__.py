"""Audit rules: checks written as files (`rules/`), their findings kept current as robots publish."""
