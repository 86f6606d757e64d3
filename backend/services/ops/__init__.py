"""Running the server: the ledger, the server log, the store monitor, result caches."""
