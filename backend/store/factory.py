"""Opening the store named in the settings."""

from __future__ import annotations

import httpx

from segb_server.backend.config import Settings
from segb_server.backend.store.base import Store
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.backend.store.sparql_http import SparqlHttpStore
from segb_server.backend.store.virtuoso import VirtuosoStore


def open_store(settings: Settings) -> Store:
    """Build the adapter for `settings.store`; remote stores are not contacted here."""
    if settings.store == "oxigraph":
        return OxigraphStore(settings.graph_uri, settings.data_dir / "oxigraph")
    if settings.store == "memory":
        return OxigraphStore(settings.graph_uri)
    if settings.store == "virtuoso":
        return VirtuosoStore(
            endpoint=settings.virtuoso_endpoint,
            user=settings.virtuoso_user,
            password=settings.virtuoso_password,
            graph_uri=settings.graph_uri,
            timeout_seconds=settings.store_timeout_seconds,
            ping_timeout_seconds=settings.ping_timeout_seconds,
        )
    auth = httpx.BasicAuth(settings.sparql_user, settings.sparql_password) if settings.sparql_user else None
    return SparqlHttpStore(
        query_endpoint=settings.sparql_query_endpoint,
        update_endpoint=settings.sparql_update_endpoint or settings.sparql_query_endpoint,
        graph_uri=settings.graph_uri,
        auth=auth,
        timeout_seconds=settings.store_timeout_seconds,
        ping_timeout_seconds=settings.ping_timeout_seconds,
    )
