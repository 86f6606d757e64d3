"""Keeping views current from the journal's stream of new triples: the keeper's thread, a batch's new triples
(`Delta`), the views' SQLite databases, and queries kept as rows (`kept_queries`)."""
