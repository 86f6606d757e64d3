"""Triple store adapters behind one protocol (`base.Store`)."""
