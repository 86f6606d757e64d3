"""Turning an ingest request body (JSON as the PyPI client sends it, or raw RDF, maybe gzipped) into RDF bytes."""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass

import jiter
from pydantic import ConfigDict, Field, ValidationError
from pyoxigraph import RdfFormat

from segb_server.backend.services.errors import EmptyPayload, InvalidPayload, PayloadTooLarge, UnsupportedMediaType
from segb_server.backend.services.text import UnicodeModel, surrogate_at

RAW_RDF_TYPES = {
    "text/turtle": RdfFormat.TURTLE,
    "application/x-turtle": RdfFormat.TURTLE,
    "application/n-triples": RdfFormat.N_TRIPLES,
}
ACCEPTED_TYPES = "application/json, text/turtle or application/n-triples"
MAX_USER_LENGTH = 256


class IngestRequest(UnicodeModel):
    """The JSON body `SEGBPublisher.publish_turtle` posts."""

    model_config = ConfigDict(
        json_schema_extra={
            "examples": [
                {
                    "ttl_content": "@prefix prov: <http://www.w3.org/ns/prov#> .\n"
                    "<https://example.org/robot/ari> a prov:Agent .\n",
                    "user": "ari",
                }
            ]
        }
    )

    ttl_content: str = Field(description="A Turtle document: the robot's whole accumulated graph, or a part.")
    user: str | None = Field(None, description="Name the client claims; kept as 'claimed user'.")


class DeleteAllRequest(UnicodeModel):
    """The JSON body `SEGBPublisher.delete_all_ttls` posts."""

    user: str | None = Field(None, description="Name the client claims.")


@dataclass(frozen=True)
class RdfPayload:
    """RDF text to ingest, its syntax, and who the client says it is."""

    data: bytes
    rdf_format: RdfFormat
    claimed_user: str | None


def media_type(content_type: str | None) -> str:
    return (content_type or "").split(";", 1)[0].strip().lower()


def decode_ingest_body(
    body: bytes,
    *,
    content_type: str | None,
    content_encoding: str | None,
    claimed_user: str | None,
    max_decompressed_bytes: int,
) -> RdfPayload:
    """Validate and unwrap a POST /ttl body. Raises the service error that names what is wrong."""
    kind = media_type(content_type)
    if kind != "application/json" and kind not in RAW_RDF_TYPES:
        shown = kind or "no Content-Type"
        raise UnsupportedMediaType(f"Unsupported Content-Type '{shown}'; send {ACCEPTED_TYPES}.")
    check_text("user", claimed_user)
    body = decompress(body, content_encoding, max_decompressed_bytes)
    if kind == "application/json":
        request = _parse_json_body(body)
        if _blank(request.ttl_content):
            raise EmptyPayload("'ttl_content' is empty; send a Turtle document.")
        return RdfPayload(request.ttl_content.encode("utf-8"), RdfFormat.TURTLE, request.user)
    if _blank(body):
        raise EmptyPayload("The request body is empty; send an RDF document.")
    return RdfPayload(body, RAW_RDF_TYPES[kind], claimed_user)


def _blank(text: str | bytes) -> bool:
    # Not `text.strip()`: that copies a whole re-sent graph only to see it is not empty.
    return not text or text.isspace()


def decompress(body: bytes, content_encoding: str | None, limit: int) -> bytes:
    """Undo `Content-Encoding: gzip`, refusing to inflate past `limit` bytes (no zip bombs)."""
    encoding = (content_encoding or "identity").strip().lower()
    if encoding == "identity":
        return body
    if encoding != "gzip":
        raise UnsupportedMediaType(f"Unsupported Content-Encoding '{encoding}'; use gzip or none.")
    output = bytearray()
    remaining = body
    while remaining:
        inflater = zlib.decompressobj(16 + zlib.MAX_WBITS)
        try:
            output += inflater.decompress(remaining, limit + 1 - len(output))
        except zlib.error as error:
            raise InvalidPayload(f"The gzip body cannot be decompressed: {error}.") from None
        if len(output) > limit or inflater.unconsumed_tail:
            raise PayloadTooLarge(f"The decompressed body is over {limit} bytes (MAX_DECOMPRESSED_BYTES).")
        if not inflater.eof:
            raise InvalidPayload("The gzip body is truncated.")
        remaining = inflater.unused_data  # a further gzip member, if any
    return bytes(output)


def _parse_json_body(body: bytes) -> IngestRequest:
    try:
        document = json_document(body)
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise InvalidPayload(f"The body is not valid JSON: {error}.") from None
    except RecursionError:
        raise InvalidPayload("The JSON body nests arrays or objects too deeply; send a flat ingest request.") from None
    try:
        request = IngestRequest.model_validate(document)
    except ValidationError as error:
        problems = "; ".join(
            f"{'.'.join(str(part) for part in issue['loc']) or 'body'}: {issue['msg']}" for issue in error.errors()
        )
        raise InvalidPayload(f"The JSON body is not an ingest request ({problems}).") from None
    for field in ("ttl_content", "user"):
        check_text(field, getattr(request, field))
    return request


def json_document(body: bytes) -> object:
    """The JSON document, a key given twice at any depth refused. jiter reads a robot's whole re-sent graph in
    half the time of the standard library; whatever it refuses (a key twice, bad syntax, a lone surrogate, UTF-16)
    is read again by the standard library, whose refusals name the problem as the API always has."""
    try:
        return jiter.from_json(body, catch_duplicate_keys=True)
    except ValueError:
        return json.loads(body, object_pairs_hook=_without_duplicate_keys)


def check_text(field: str, value: str | None) -> None:
    """Text that will be stored, hashed and logged must be real Unicode (services/text.py says why). Refused
    naming the field, before anything is written."""
    if value is None:
        return
    position = surrogate_at(value)
    if position is not None:
        raise InvalidPayload(
            f"'{field}' holds an unpaired surrogate ({value[position]!a}) at character {position}: "
            "not valid Unicode text."
        )
    if field == "user" and len(value) > MAX_USER_LENGTH:
        raise InvalidPayload(f"'user' is {len(value)} characters long; the most is {MAX_USER_LENGTH}.")


def _without_duplicate_keys(pairs: list[tuple[str, object]]) -> dict[str, object]:
    document: dict[str, object] = {}
    for key, value in pairs:
        if key in document:
            raise InvalidPayload(f"The JSON body gives '{key}' more than once; give each field once.")
        document[key] = value
    return document
