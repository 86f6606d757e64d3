"""Databases for the server's own state (the journal, shared contexts): SQLite files in DATA_DIR by default,
or PostgreSQL (`STATE_URL=postgresql://…`) when API processes on several hosts share it."""
