"""Errors the services raise; `backend/api/errors.py` turns each class into one HTTP status."""

from __future__ import annotations

from typing import Any

from segb_server.backend.state.database import StateUnavailable
from segb_server.backend.store.base import StoreError

# What background work waits out and retries: the triple store or the state database is away (or failing).
OUTAGES: tuple[type[Exception], ...] = (StoreError, StateUnavailable)


class ServiceError(Exception):
    """Base of every error a caller can act on. `code` is a stable machine-readable name."""

    code = "error"

    def __init__(self, message: str, **details: Any) -> None:
        super().__init__(message)
        self.message = message
        self.details = details


class InvalidRdf(ServiceError):
    """The payload is not valid RDF in its declared syntax."""

    code = "invalid_rdf"

    def __init__(self, message: str, *, syntax: str, line: int | None = None, column: int | None = None) -> None:
        where = f" at line {line}, column {column}" if line is not None else ""
        super().__init__(f"Invalid {syntax}{where}: {message}", line=line, column=column)


class EmptyPayload(ServiceError):
    """The request carries no content to ingest."""

    code = "empty_payload"


class InvalidPayload(ServiceError):
    """The request body is not of the expected shape (bad JSON, wrong field types, bad gzip)."""

    code = "invalid_payload"


class UnsupportedMediaType(ServiceError):
    """The body's Content-Type or Content-Encoding is not one the endpoint reads."""

    code = "unsupported_media_type"


class PayloadTooLarge(ServiceError):
    """The body, its decompressed form, or its triple count is over a configured limit."""

    code = "payload_too_large"


class NotFound(ServiceError):
    """The named resource (report, receipt, review case…) does not exist."""

    code = "not_found"


class Conflict(ServiceError):
    """The request is valid but the resource is no longer in a state that allows it (a decided review)."""

    code = "conflict"


class InvalidParameter(ServiceError):
    """A query-string or body parameter has a value the service cannot use."""

    code = "invalid_parameter"

    def __init__(self, parameter: str, message: str) -> None:
        super().__init__(f"Parameter '{parameter}': {message}", parameter=parameter)


class InvalidQuery(ServiceError):
    """A user's SPARQL query is malformed or not allowed (updates, federation)."""

    code = "invalid_query"


class ViewNotReady(ServiceError):
    """A view kept from the journal (the graph index) is still being built: the request can be repeated soon."""

    code = "view_not_ready"
