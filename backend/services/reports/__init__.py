"""Audit reports: the `.rq` files under `sparql/reports/`, served from their kept rows or evaluated in full."""
