"""Loading RDF files into the store in batches, reporting progress by bytes read."""

from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import dataclass
from itertools import islice
from pathlib import Path
from typing import IO, cast

from pyoxigraph import RdfFormat, parse

from segb_server.backend.services.errors import InvalidParameter
from segb_server.backend.services.ingest.parsing import invalid_rdf, parse_triples
from segb_server.backend.services.ingest.skolem import might_contain_blank_nodes
from segb_server.backend.store.base import Store

BATCH_TRIPLES = 20_000
FILE_FORMATS = {".ttl": RdfFormat.TURTLE, ".turtle": RdfFormat.TURTLE, ".nt": RdfFormat.N_TRIPLES}

Progress = Callable[[int], None]


@dataclass(frozen=True)
class ImportResult:
    path: Path
    triples_read: int
    triples_new: int


def format_for(path: Path) -> RdfFormat:
    try:
        return FILE_FORMATS[path.suffix.lower()]
    except KeyError:
        raise InvalidParameter("file", f"{path.name}: use a .ttl or .nt file") from None


def import_file(store: Store, path: Path, *, skolem_base: str, progress: Progress) -> ImportResult:
    """Insert the file's triples; `progress(n)` is told about every n bytes consumed.

    Files that may hold blank nodes are parsed whole, because skolemisation needs each blank node's full
    surroundings; the others stream, so memory stays at one batch.
    """
    rdf_format = format_for(path)
    if _file_might_contain_blank_nodes(path):
        data = path.read_bytes()
        quads = parse_triples(data, rdf_format, max_triples=len(data), skolem_base=skolem_base)
        new = sum(store.insert_new(quads[i : i + BATCH_TRIPLES]) for i in range(0, len(quads), BATCH_TRIPLES))
        progress(len(data))
        return ImportResult(path, len(quads), new)
    read = new = 0
    with path.open("rb") as raw:
        parser = parse(cast(IO[bytes], _CountingReader(raw, progress)), rdf_format)
        try:
            while batch := list(islice(parser, BATCH_TRIPLES)):
                read += len(batch)
                new += store.insert_new(batch)
        except SyntaxError as error:
            raise invalid_rdf(error, rdf_format) from None
    return ImportResult(path, read, new)


def _file_might_contain_blank_nodes(path: Path) -> bool:
    with path.open("rb") as file:
        previous = b""
        while chunk := file.read(1 << 20):
            if might_contain_blank_nodes(previous[-1:] + chunk):
                return True
            previous = chunk
    return False


class _CountingReader(io.RawIOBase):
    def __init__(self, raw: io.BufferedReader, progress: Progress) -> None:
        self._raw = raw
        self._progress = progress

    def readable(self) -> bool:
        return True

    def readinto(self, target: bytearray | memoryview) -> int:  # type: ignore[override]
        size = self._raw.readinto(target)
        if size:
            self._progress(size)
        return size or 0
