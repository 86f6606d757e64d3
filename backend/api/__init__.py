"""HTTP API: routes translate HTTP into service calls; errors map to statuses in `errors.py`."""
