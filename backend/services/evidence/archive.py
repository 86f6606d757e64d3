"""Reading a bundle's zip archive strictly: it must be exactly the plain archive the server writes, so that what a
streaming reader, an unzip tool or a file manager shows is what the check read, and reading it is bounded.

Walked from its first byte: the local entries one after the other with no gap, then the central directory naming
those same entries at those same offsets with the same fields, then the end record, and nothing else (no comment,
no bytes before or after). Each entry a plain file (no link, no directory, no encryption, no data descriptor, no
extra field, which some tools read as another name), stored or deflated. Every size is checked before anything
is inflated (against the `limit` in all, and against a ratio no file the server writes reaches), and inflating
stops one byte past the size the headers declare.
"""

from __future__ import annotations

import stat
import struct
import zlib
from dataclasses import dataclass
from typing import BinaryIO

LOCAL = struct.Struct("<4s5H3L2H")  # signature, version needed, flags, method, time, date, crc, sizes, name, extra
CENTRAL = struct.Struct("<4s6H3L5H2L")  # … made by, …, comment, disk, internal and external attributes, offset
END = struct.Struct("<4s4H2LH")  # signature, disks, entries here and in all, directory size and offset, comment
MOST_ENTRIES = 64  # a bundle has seven; more are named one by one
MOST_INFLATION = 100  # deflated N-Triples, JSON lines and HTML stay far below; zeros inflate a thousandfold
INFLATION_CHECKED_FROM = 1 << 20  # tiny files compress oddly and cost nothing
STORED, DEFLATED = 0, 8
NAMES_IN_UTF8 = 0x800
HARMLESS_FLAGS = NAMES_IN_UTF8 | 0x6  # 0x6: the compression level the writer chose
PLAIN_FILE_ATTRIBUTES = 0x01 | 0x20  # MS-DOS read-only and archive; directory, hidden, system… are not plain
CHUNK = 1 << 16


class ArchiveRefused(Exception):
    """The archive is not one the check reads: the message says why."""


@dataclass(frozen=True)
class Entry:
    name: str
    method: int
    crc: int
    compressed: int
    size: int
    data_offset: int


def entries_of(file: BinaryIO, limit: int) -> list[Entry]:
    """The archive's entries in order, once its structure and sizes are checked (ArchiveRefused otherwise)."""
    length = file.seek(0, 2)
    count, directory_size, directory_offset = _end_record(file, length)
    file.seek(directory_offset)
    directory = file.read(directory_size)
    entries: list[Entry] = []
    at = position = 0  # in the directory; in the archive, where the next local entry must start
    for _ in range(count):
        item, at = _central_entry(directory, at)
        if item.offset != position:
            raise ArchiveRefused(_gap(position, item.offset))
        entries.append(_local_entry(file, item))
        position = entries[-1].data_offset + item.compressed
    if at != directory_size:
        raise ArchiveRefused("the archive's central directory holds more than its entries")
    if position != directory_offset:
        raise ArchiveRefused(_gap(position, directory_offset))
    _check_sizes(entries, limit)
    return entries


def read_entry(file: BinaryIO, entry: Entry) -> bytes:
    """The entry's bytes, inflated in chunks that stop one byte past its declared size, and checked."""
    file.seek(entry.data_offset)
    data = file.read(entry.size) if entry.method == STORED else _inflated(file, entry)
    if len(data) != entry.size or zlib.crc32(data) != entry.crc:
        raise ArchiveRefused(f"{entry.name} is damaged: it is not the {entry.size} bytes its checksum covers")
    return data


def _inflated(file: BinaryIO, entry: Entry) -> bytes:
    inflater, out, left = zlib.decompressobj(-15), bytearray(), entry.compressed
    try:
        while left and not inflater.eof:
            chunk = file.read(min(CHUNK, left))
            left -= len(chunk)
            out += inflater.decompress(chunk, entry.size + 1 - len(out))
            if len(out) > entry.size:
                raise ArchiveRefused(f"{entry.name} inflates to more than the {entry.size} bytes its headers declare")
    except zlib.error as error:
        raise ArchiveRefused(f"{entry.name} is damaged: its compressed data does not inflate ({error})") from None
    if left or not inflater.eof or inflater.unused_data:
        raise ArchiveRefused(f"{entry.name} is damaged: its compressed data does not end where its headers say")
    return bytes(out)


def _end_record(file: BinaryIO, length: int) -> tuple[int, int, int]:
    if length < LOCAL.size + CENTRAL.size + END.size:
        raise ArchiveRefused(f"not a readable evidence bundle: {length} bytes are too few for a zip archive")
    file.seek(length - END.size)
    tail = file.read(END.size)
    if len(tail) < END.size or not tail.startswith(b"PK\x05\x06"):
        raise ArchiveRefused(_why_no_end(file, length))
    _, disk, directory_disk, here, count, size, offset, comment = END.unpack(tail)
    if comment:
        raise ArchiveRefused(f"the archive carries a comment ({comment} bytes): a bundle has none")
    if disk or directory_disk or here != count or not 0 < count <= MOST_ENTRIES:
        raise ArchiveRefused(f"the archive's end record is not a bundle's ({count} entries, disk {disk})")
    if size > count * (CENTRAL.size + 0xFFFF):
        raise ArchiveRefused(f"the archive's central directory is larger than {count} entries need")
    # Bytes before the first entry shift where the directory lies from where the end record says it is (zipfile
    # and some unzip tools allow for them; a streaming reader reads them as entries).
    before = length - END.size - size - offset
    if before > 0:
        raise ArchiveRefused(f"the archive holds {before} bytes before its first entry, which it does not list")
    if before:
        raise ArchiveRefused("not a readable evidence bundle: its end record does not point at its central directory")
    return count, size, offset


def _why_no_end(file: BinaryIO, length: int) -> str:
    """Why the last bytes are not an end record: a comment after it, bytes after it, or no zip archive at all."""
    start = max(0, length - END.size - 0xFFFF - CHUNK)
    file.seek(start)
    window = file.read(length - start)
    found = window.rfind(b"PK\x05\x06")
    if found < 0 or found + END.size > len(window):
        return "not a readable evidence bundle: no zip end record (a truncated file, or not a zip archive)"
    comment = END.unpack_from(window, found)[-1]
    if comment:
        return f"the archive carries a comment ({comment} bytes): a bundle has none"
    return f"{len(window) - found - END.size} bytes follow the end of the archive: a bundle has none"


@dataclass(frozen=True)
class _Central:
    """What the central directory says of one entry: the local header must say the same."""

    fields: tuple[int, ...]  # version needed, flags, method, time, date, crc, compressed, size
    raw_name: bytes
    name: str
    offset: int

    @property
    def compressed(self) -> int:
        return self.fields[6]


def _central_entry(directory: bytes, at: int) -> tuple[_Central, int]:
    if len(directory) < at + CENTRAL.size or not directory.startswith(b"PK\x01\x02", at):
        raise ArchiveRefused("not a readable evidence bundle: its central directory is damaged")
    _, _made_by, *fields, name_length, extra, comment, disk, internal, external, offset = CENTRAL.unpack_from(
        directory, at
    )
    raw_name = directory[at + CENTRAL.size : at + CENTRAL.size + name_length]
    name = _decoded(raw_name, fields[1])
    problem = _entry_problem(fields, extra + comment, disk, internal, external)
    if problem:
        raise ArchiveRefused(f"{name} {problem}")
    return _Central(tuple(fields), raw_name, name, offset), at + CENTRAL.size + name_length + extra + comment


def _entry_problem(fields: list[int], extra: int, disk: int, internal: int, external: int) -> str | None:
    """What makes an entry other than a plain file the server writes, or None."""
    needed, flags, method, *_, compressed, size = fields
    mode, attributes = external >> 16, external & 0xFFFF
    checks = [
        (flags & 0x1, "is encrypted"),
        (flags & 0x8, "uses a data descriptor (sizes after its data, which the server never writes)"),
        (flags & ~HARMLESS_FLAGS, f"has flags the server never sets ({flags:#06x})"),
        (method not in (STORED, DEFLATED), f"is compressed with method {method}: a bundle is stored or deflated"),
        (method == STORED and compressed != size, "is stored, yet its two sizes differ"),
        (needed > 20, f"needs zip version {needed / 10}: a bundle needs 2.0"),
        (extra, "carries extra fields or a comment: some tools read another name or size from them"),
        (disk or internal & ~1, "has attributes of a split or special archive"),
        (stat.S_ISLNK(mode), "is a symbolic link"),
        (stat.S_IFMT(mode) not in (0, stat.S_IFREG) or mode & 0o7000, f"is not a plain file (mode {mode:o})"),
        (attributes & ~PLAIN_FILE_ATTRIBUTES, f"has file attributes a plain file has not ({attributes:#x})"),
    ]
    return next((problem for failed, problem in checks if failed), None)


def _local_entry(file: BinaryIO, central: _Central) -> Entry:
    file.seek(central.offset)
    header = file.read(LOCAL.size)
    if len(header) < LOCAL.size or not header.startswith(b"PK\x03\x04"):
        raise ArchiveRefused(f"{central.name}: its local header is missing where the central directory points")
    _, *fields, name_length, extra = LOCAL.unpack(header)
    raw_name = file.read(name_length)
    if tuple(fields) != central.fields or raw_name != central.raw_name or extra:
        raise ArchiveRefused(
            f"{central.name}: its local header disagrees with the central directory (a streaming reader and an "
            "unzip tool would show different files)"
        )
    _needed, _flags, method, _time, _date, crc, compressed, size = fields
    return Entry(central.name, method, crc, compressed, size, central.offset + LOCAL.size + name_length)


def _check_sizes(entries: list[Entry], limit: int) -> None:
    mebibytes = f"{limit >> 20} MiB"
    for entry in entries:
        if entry.size > limit:
            raise ArchiveRefused(f"{entry.name} would inflate to {entry.size} bytes, more than the {mebibytes} this "
                                 "check reads (--max-size)")  # fmt: skip
        if entry.compressed > entry.size + (entry.size >> 10) + 64:  # deflate adds far less to what it cannot shrink
            raise ArchiveRefused(f"{entry.name} holds {entry.compressed} bytes of data for {entry.size} bytes")
        if entry.size >= INFLATION_CHECKED_FROM and entry.size > MOST_INFLATION * entry.compressed:
            raise ArchiveRefused(
                f"{entry.name} would inflate {entry.size // max(entry.compressed, 1)}-fold ({entry.compressed} bytes "
                f"to {entry.size}): a zip bomb, not a file the server writes"
            )
    total = sum(entry.size for entry in entries)
    if total > limit:
        raise ArchiveRefused(f"the bundle's files would inflate to {total} bytes, more than the {mebibytes} this "
                             "check reads (--max-size)")  # fmt: skip


def _gap(expected: int, found: int) -> str:
    if found > expected:
        return f"the archive holds {found - expected} bytes it does not list, between its entries (offset {expected})"
    return f"not a readable evidence bundle: its entries overlap at offset {found}"


def _decoded(raw: bytes, flags: int) -> str:
    """The name as zip tools show it (UTF-8 when flagged, else code page 437), control characters escaped."""
    try:
        name = raw.decode("utf-8" if flags & NAMES_IN_UTF8 else "cp437")
    except UnicodeDecodeError:
        raise ArchiveRefused(f"an entry's name is not UTF-8 as its flags say: {raw!r}") from None
    return name if name.isprintable() else ascii(name)
