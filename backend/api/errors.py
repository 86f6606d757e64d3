"""Every error becomes one JSON shape, `{"detail", "error", ...}`, with one status per error class."""

from __future__ import annotations

import logging

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from segb_server.backend.auth import AuthenticationFailed, PermissionDenied
from segb_server.backend.services import errors as service_errors
from segb_server.backend.services.formats import NotAcceptable
from segb_server.backend.services.ingest.service import JournalBacklogFull
from segb_server.backend.services.sparql.runner import QueryTooBig
from segb_server.backend.services.writing.journal import StorageFull
from segb_server.backend.state.database import StateUnavailable
from segb_server.backend.store.base import QueryTimeout, StoreError, StoreRejectedQuery, StoreUnavailable

logger = logging.getLogger("segb.api")


class ReferenceQueryRefused(service_errors.ServiceError):
    """A query refused on the reference's own endpoints (/query): 422 there, as the reference answers; the
    standard /sparql keeps the protocol's 400."""

    code = "invalid_query"


RETRY_AFTER_SECONDS = 5

STATUS_BY_ERROR: list[tuple[type[Exception], int]] = [
    (service_errors.InvalidRdf, 400),
    (service_errors.InvalidQuery, 400),
    (StoreRejectedQuery, 400),
    (AuthenticationFailed, 401),
    (PermissionDenied, 403),
    (service_errors.NotFound, 404),
    (NotAcceptable, 406),
    (service_errors.Conflict, 409),
    (service_errors.PayloadTooLarge, 413),
    (StorageFull, 507),
    (JournalBacklogFull, 503),
    (service_errors.UnsupportedMediaType, 415),
    (service_errors.EmptyPayload, 422),
    (service_errors.InvalidPayload, 422),
    (service_errors.InvalidParameter, 422),
    (ReferenceQueryRefused, 422),
    (service_errors.ViewNotReady, 503),
    (QueryTimeout, 503),
    (QueryTooBig, 503),
    (StoreUnavailable, 503),
    (StateUnavailable, 503),
    (StoreError, 502),
]


def error_body(status: int, detail: object, code: str, **extra: object) -> dict[str, object]:
    return {"detail": detail, "error": code, "status": status, **extra}


def _service_error(request: Request, error: Exception) -> JSONResponse:
    status = next(code for kind, code in STATUS_BY_ERROR if isinstance(error, kind))
    headers = {"WWW-Authenticate": "Bearer"} if status == 401 else {}
    if status in (503, 507):  # a condition that passes: say when to try again
        headers["Retry-After"] = str(getattr(error, "details", {}).get("retry_after", RETRY_AFTER_SECONDS))
    if isinstance(error, service_errors.ServiceError):
        body = error_body(status, error.message, error.code, **error.details)
    elif isinstance(error, StoreUnavailable):
        services = getattr(request.app.state, "services", None)
        kind = services.store.kind if services is not None else "store"
        body = error_body(status, f"The triple store ({kind}) is unavailable: {error}", "store_unavailable")
    elif isinstance(error, QueryTimeout):
        body = error_body(status, str(error), "query_timeout", timeout_seconds=error.seconds)
    elif isinstance(error, QueryTooBig):
        body = error_body(status, str(error), "query_memory", memory_bytes=error.limit)
    elif isinstance(error, StateUnavailable):
        body = error_body(status, str(error), "state_unavailable")
    elif isinstance(error, StoreRejectedQuery):
        body = error_body(status, f"The store rejected the query: {error}", "invalid_query")
    elif isinstance(error, StoreError):
        logger.error("store error on %s %s: %s", request.method, request.url.path, error)
        body = error_body(status, f"The triple store failed: {error}", "store_error")
    else:
        body = error_body(status, str(error), type(error).__name__.lower())
    return JSONResponse(body, status_code=status, headers=headers)


def _validation_error(request: Request, error: RequestValidationError) -> JSONResponse:
    problems = [
        {
            "loc": list(issue.get("loc", ())),
            "msg": _said(issue),
            "type": issue.get("type", ""),
        }
        for issue in error.errors()
    ]
    summary = "; ".join(f"{'.'.join(str(part) for part in p['loc'])}: {p['msg']}" for p in problems)
    return JSONResponse(error_body(422, problems, "invalid_request", message=summary), status_code=422)


def _said(issue: dict[str, object]) -> str:
    """An issue's message; for a body that is not JSON, what the parser met and where (FastAPI says only "JSON
    decode error", at the character offset it puts in `loc`)."""
    message = str(issue.get("msg", ""))
    context = issue.get("ctx")
    if issue.get("type") == "json_invalid" and isinstance(context, dict) and context.get("error"):
        loc = issue.get("loc")
        offset = loc[-1] if isinstance(loc, tuple | list) and len(loc) > 1 else None
        where = f" at character {offset}" if isinstance(offset, int) else ""
        return f"the body is not JSON: {context['error']}{where}"
    return message


def _http_error(request: Request, error: StarletteHTTPException) -> JSONResponse:
    code = {404: "not_found", 405: "method_not_allowed"}.get(error.status_code, "http_error")
    return JSONResponse(
        error_body(error.status_code, error.detail, code), status_code=error.status_code, headers=error.headers
    )


def install_error_handlers(app: FastAPI) -> None:
    for kind, _ in STATUS_BY_ERROR:
        app.add_exception_handler(kind, _service_error)
    app.add_exception_handler(RequestValidationError, _validation_error)  # type: ignore[arg-type]
    app.add_exception_handler(StarletteHTTPException, _http_error)  # type: ignore[arg-type]


ERROR_SCHEMA = {
    "title": "Error",
    "type": "object",
    "required": ["detail", "error", "status"],
    "properties": {
        "detail": {
            "anyOf": [{"type": "string"}, {"type": "array", "items": {"type": "object"}}],
            "description": "What went wrong, for people; a list of problems for an invalid request.",
        },
        "error": {"type": "string", "description": "A stable machine-readable code."},
        "status": {"type": "integer"},
        "message": {"type": "string"},
        "line": {"type": ["integer", "null"]},
        "column": {"type": ["integer", "null"]},
    },
    "additionalProperties": True,
}


def document_error_shape(app: FastAPI) -> None:
    """Make the OpenAPI description say what errors really look like: FastAPI documents its own 422 body
    (`HTTPValidationError`), which the handlers above replace with the one error shape."""
    generate = app.openapi

    def openapi() -> dict[str, object]:
        if app.openapi_schema is None:
            schema = generate()
            schemas = schema.setdefault("components", {}).setdefault("schemas", {})
            schemas["HTTPValidationError"] = ERROR_SCHEMA
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]
