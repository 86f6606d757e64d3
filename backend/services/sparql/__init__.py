"""SPARQL the server runs or accepts: the query catalog, the read-only guard, limits, examples."""
