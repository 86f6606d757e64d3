"""A page of a catalog query evaluated by the store: rows `offset`…`offset+limit`, on every store."""

from __future__ import annotations

from segb_server.backend.services.sparql.catalog import paged
from segb_server.backend.store.base import Bindings, SelectResult, Store, select


def evaluated_page(store: Store, text: str, bindings: Bindings, limit: int, offset: int) -> SelectResult:
    """Up to `limit` rows of the query's answer from `offset` on, in its order."""
    sorted_rows = store.max_sorted_rows
    if sorted_rows is None or offset + limit <= sorted_rows:
        return select(store, paged(text, limit, offset), bindings)
    # Past what the store sorts for a LIMIT (Virtuoso: SR353), the page is cut from the whole answer, which the
    # store sorts without that bound. Only queries evaluated in full come here, and only for their deep pages.
    result = select(store, text, bindings)
    return SelectResult(result.columns, result.rows[offset : offset + limit])
