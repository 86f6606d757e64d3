"""The events graph: drawn from the graph index, one resource at a time from the store, exported whole."""
