"""SEGB web UI: server-rendered pages that get every piece of data from the backend API over HTTP."""
