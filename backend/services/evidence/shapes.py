"""The JSON files of a bundle, read into typed values field by field, so the checks work on what the builder
writes and anything else is one `Malformed` naming the file, the line and the field (not a traceback halfway
through a check). Standard library only, as the rest of the verifier."""

from __future__ import annotations

import json
import types
from dataclasses import dataclass
from typing import Any, TypeVar, get_args, get_type_hints

from segb_server.backend.services.evidence import layout
from segb_server.backend.services.writing.receipts import Receipt
from segb_server.backend.services.writing.redaction import DIGEST_BYTES, canonical_json

T = TypeVar("T")
_KINDS = {int: "an integer", str: "a string", list: "a list", dict: "an object"}
_RECEIPT_FIELDS = get_type_hints(Receipt)  # name → int, str, str | None, int | None


class Malformed(ValueError):
    """A bundle's file is not shaped as the builder writes it: the message says where."""


def json_of(data: bytes, where: str) -> object:
    try:
        value = json.loads(data)
    except (ValueError, RecursionError) as error:  # RecursionError: arrays nested thousands deep
        raise Malformed(f"{where} is not JSON: {error}") from None
    try:  # every hash is taken over UTF-8: a lone surrogate ("\ud800") has no UTF-8 form
        canonical_json(value)
    except UnicodeEncodeError:
        raise Malformed(f"{where} holds text that is not Unicode (a lone surrogate)") from None
    return value


class Fields:
    """A JSON object whose fields are read with the type they must have."""

    def __init__(self, value: object, where: str) -> None:
        self.value = _typed(value, dict, where)
        self.where = where

    def get(self, key: str, kind: type[T]) -> T:
        if key not in self.value:
            raise Malformed(f"{self.where}: {key} is missing")
        return _typed(self.value[key], kind, f"{self.where}: {key}")

    def optional(self, key: str, kind: type[T]) -> T | None:
        value = self.value.get(key)
        return None if value is None else _typed(value, kind, f"{self.where}: {key}")

    def fields(self, key: str) -> Fields:
        return Fields(self.get(key, dict), f"{self.where}: {key}")

    def items(self, key: str, kind: type[T]) -> list[T]:
        return [_typed(item, kind, f"{self.where}: {key} {n}") for n, item in enumerate(self.get(key, list), 1)]

    def each(self, key: str) -> list[Fields]:
        return [Fields(item, f"{self.where}: {key} {n}") for n, item in enumerate(self.get(key, list), 1)]


def _typed(value: object, kind: type[T], where: str) -> T:
    if (isinstance(value, bool) and kind is not bool) or not isinstance(value, kind):  # JSON true is no integer
        raise Malformed(f"{where} is not {_KINDS[kind]}")
    return value


@dataclass(frozen=True)
class Erasure:
    """An erasure in the bundle's range, as the manifest tells it."""

    sequence: int
    recorded_at: str
    user: str
    kind: str
    reason: str
    triples_removed: int
    receipts_in_window: list[int]


@dataclass(frozen=True)
class Manifest:
    key_fingerprint: str
    files: dict[str, str]  # name → SHA-256
    head: tuple[int, str] | None  # the signed head: sequence, receipt_hash
    redactions: list[Erasure]


def manifest_of(data: bytes) -> Manifest:
    manifest = Fields(json_of(data, layout.MANIFEST), layout.MANIFEST)
    listed = manifest.fields("files")
    head = manifest.fields("chain").optional("head", dict)
    chain_head = Fields(head, f"{layout.MANIFEST}: chain: head") if head is not None else None
    return Manifest(
        manifest.fields("server").get("key_fingerprint", str),
        {name: listed.get(name, str) for name in listed.value},
        (chain_head.get("sequence", int), chain_head.get("receipt_hash", str)) if chain_head else None,
        [_erasure(item) for item in manifest.each("redactions")],
    )


def _erasure(item: Fields) -> Erasure:
    return Erasure(
        item.get("sequence", int),
        item.get("recorded_at", str),
        item.get("user", str),
        item.get("kind", str),
        item.get("reason", str),
        item.get("triples_removed", int),
        item.items("receipts_in_window", int),
    )


@dataclass(frozen=True)
class Redacted:
    """What an erasure's record says it removed from one post."""

    sequence: int
    triples_removed: int
    remaining_sha256: str | None


@dataclass(frozen=True)
class Link:
    """One line of receipts.jsonl: a receipt, and for an erasure its record (as carried: its hash is checked)."""

    receipt: Receipt
    record: dict[str, Any] | None
    redacted: list[Redacted]


def chain_of(data: bytes) -> list[Link]:
    links = []
    for where, entry in _lines(data, layout.RECEIPTS):
        public = entry.fields("receipt")
        receipt = Receipt(**{name: _receipt_field(public, name, hint) for name, hint in _RECEIPT_FIELDS.items()})
        record = entry.optional("redaction", dict)
        redacted = [] if record is None else Fields(record, f"{where}: redaction").each("receipts")
        links.append(Link(receipt, record, [_redacted(item) for item in redacted]))
    return links


def _receipt_field(public: Fields, name: str, hint: Any) -> Any:
    if isinstance(hint, types.UnionType):  # `str | None`: a field older receipts do not have
        return public.optional(name, next(kind for kind in get_args(hint) if kind is not type(None)))
    return public.get(name, hint)


def _redacted(item: Fields) -> Redacted:
    return Redacted(item.get("sequence", int), item.get("triples_removed", int), item.optional("remaining_sha256", str))


@dataclass(frozen=True)
class Share:
    """One line of coverage.jsonl: what one receipt discloses, and the digests of the rest of its post."""

    sequence: int
    disclosed: list[bytes]
    withheld: bytes
    redacted: bytes


def coverage_of(data: bytes) -> list[Share]:
    return [
        Share(
            entry.get("sequence", int),
            [line.encode("utf-8") for line in entry.items("disclosed", str)],  # json_of checked they encode
            _digests(entry, "withheld"),
            _digests(entry, "redacted"),
        )
        for _where, entry in _lines(data, layout.COVERAGE)
    ]


def _digests(entry: Fields, key: str) -> bytes:
    digests = entry.items(key, str)
    for n, digest in enumerate(digests, 1):
        if len(digest) != 2 * DIGEST_BYTES or not _is_hex(digest):
            raise Malformed(f"{entry.where}: {key} {n} is not a SHA-256 digest in hex")
    return bytes.fromhex("".join(digests))


def _is_hex(text: str) -> bool:
    return all(char in "0123456789abcdefABCDEF" for char in text)


def _lines(data: bytes, name: str) -> list[tuple[str, Fields]]:
    lines = []
    for number, line in enumerate(data.splitlines(), 1):
        where = f"{name} line {number}"
        lines.append((where, Fields(json_of(line, where), where)))
    return lines
