"""Receiving robots' RDF: request bodies, parsing, skolemisation, writing, bulk imports."""
