"""Services: the logic behind the routes. No FastAPI imports here; errors come from `errors.py`."""
