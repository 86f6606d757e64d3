"""Reading form posts without an extra dependency, with a size cap: URL-encoded forms, and multipart forms (a
file field among text fields) through the standard library's MIME parser."""

from __future__ import annotations

from email import policy
from email.parser import BytesParser
from urllib.parse import parse_qsl

from starlette.requests import Request

MAX_FORM_BYTES = 1024 * 1024
URLENCODED = "application/x-www-form-urlencoded"
MULTIPART = "multipart/form-data"


class BadForm(Exception):
    """The post is not a form of the expected kind, is too large, or is not UTF-8 text."""


async def read_form(request: Request, max_bytes: int = MAX_FORM_BYTES) -> dict[str, str]:
    if _kind(request) != URLENCODED:
        raise BadForm(f"Expected a form post ({URLENCODED}).")
    body = await _body(request, max_bytes)
    try:
        return dict(parse_qsl(body.decode("utf-8"), keep_blank_values=True))
    except UnicodeDecodeError:
        raise BadForm("The form is not valid UTF-8.") from None


async def read_upload_form(request: Request, max_bytes: int) -> dict[str, str]:
    """Every field of a URL-encoded or multipart form as text; a file field holds the file's content."""
    if _kind(request) == URLENCODED:
        return await read_form(request, max_bytes)
    if _kind(request) != MULTIPART:
        raise BadForm(f"Expected a form post ({URLENCODED} or {MULTIPART}).")
    body = await _body(request, max_bytes)
    head = f"Content-Type: {request.headers['content-type']}\r\n\r\n".encode("latin-1", "replace")
    message = BytesParser(policy=policy.HTTP).parsebytes(head + bytes(body))
    if not message.is_multipart():
        raise BadForm("The form's parts cannot be read (no multipart boundary).")
    fields: dict[str, str] = {}
    for part in message.iter_parts():
        name = part.get_param("name", header="content-disposition")
        if not isinstance(name, str):
            continue
        payload = part.get_payload(decode=True)
        try:
            fields[name] = payload.decode("utf-8") if isinstance(payload, bytes) else ""
        except UnicodeDecodeError:
            raise BadForm(f"The field '{name}' is not UTF-8 text.") from None
    return fields


def _kind(request: Request) -> str:
    return request.headers.get("content-type", "").split(";", 1)[0].strip().lower()


async def _body(request: Request, max_bytes: int) -> bytearray:
    body = bytearray()
    async for chunk in request.stream():
        body += chunk
        if len(body) > max_bytes:
            raise BadForm(f"The form is larger than {max_bytes} bytes.")
    return body
