"""The structured server log: every `segb.*` record as one JSON object per line in a size-rotated file (or a
bounded in-memory ring for a throwaway server), and the reader behind GET /logs/server.

Records carry only what the code logs: request lines hold the id, method, path (never the query string),
status, duration, user, client address and triples written; no token or body is ever logged. Each entry names
the process that wrote it (`process`, its pid): with `segb serve --workers N` the workers share one file.
Entries read back also carry the reference backend's names for the same facts (`timestamp`, `actor`, `raw`),
which its web UI reads.
"""

from __future__ import annotations

import json
import logging
import os
import re
import threading
from collections import deque
from collections.abc import Callable, Collection, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, BinaryIO
from urllib.parse import quote, unquote

from segb_server.backend.config import Settings
from segb_server.backend.services.clock import utc_iso
from segb_server.backend.state.file_lock import FileLock

ROOT_LOGGER = "segb"
LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL")
# Structured fields a record may carry (passed as `extra=` by the request logger and others).
FIELDS = ("request_id", "user", "origin_ip", "method", "path", "status", "duration_ms", "triples_written", "log_id")
REQUIRED = ("time", "level", "logger", "message")  # what every entry has; a line without them was not ours
_IRI = re.compile(r"https?(?::|%(?:25)*3A)[^\s\"'<>\\]+", re.IGNORECASE)  # `%3A`, `%253A`: encoded once, twice
# How the request log writes a path naming a person's IRI (api/request_context.py, `logged_path`): the IRI left
# out, its last segment kept.
HUMAN_PATH_PREFIX = "/humans/{iri}/"
_HUMAN_PATH = re.compile(re.escape(HUMAN_PATH_PREFIX) + r"([^\s\"]+)")
RING_ENTRIES = 5000

Entry = dict[str, Any]


def entry_of(record: logging.LogRecord) -> Entry:
    entry: Entry = {
        "time": utc_iso(record.created, timespec="milliseconds"),
        "level": record.levelname,
        "logger": record.name,
        "message": record.getMessage(),
        "process": record.process,
    }
    for name in FIELDS:
        value = record.__dict__.get(name)
        if value is not None:
            entry[name] = value
    if record.exc_info and record.exc_info[1] is not None:
        error = record.exc_info[1]
        entry["exception"] = f"{type(error).__name__}: {error}"
    return entry


def line_of(entry: Entry) -> str:
    return json.dumps(entry, ensure_ascii=False, default=str)


def with_reference_fields(entry: Entry, raw: str) -> Entry:
    """The entry plus the reference's names: `timestamp` (the time), `actor` (the user), `raw` (the log line)."""
    return {**entry, "timestamp": entry.get("time"), "actor": entry.get("user"), "raw": raw}


class _JsonLines(logging.Handler):
    """Lines appended to a size-rotated file that several processes may share: every write and rotation is made
    under an flock on `<file>.lock`, and a process whose file another one rotated away opens the current one."""

    def __init__(self, path: Path, *, max_bytes: int, backups: int) -> None:
        super().__init__()
        self.path = path
        self.max_bytes = max_bytes
        self.backups = backups
        self.writers = FileLock(path.with_name(f"{path.name}.lock"))
        self._stream: BinaryIO | None = None
        self._closed = False

    def emit(self, record: logging.LogRecord) -> None:
        if self._closed:  # a thread of the server still winding down: the log's file is no longer this handler's
            return
        try:
            data = (line_of(entry_of(record)) + "\n").encode("utf-8")
            with self.writers.held():
                stream = self._current()
                if self.backups and os.fstat(stream.fileno()).st_size + len(data) > self.max_bytes:
                    self._rotate()
                    stream = self._current()
                stream.write(data)
                stream.flush()
        except Exception:
            self.handleError(record)

    def _current(self) -> BinaryIO:
        """The open file, reopened when the path names another file now (rotated by another process)."""
        try:
            on_disk = os.stat(self.path).st_ino
        except FileNotFoundError:
            on_disk = None
        if self._stream is not None and os.fstat(self._stream.fileno()).st_ino != on_disk:
            self._stream.close()
            self._stream = None
        if self._stream is None:
            self._stream = self.path.open("ab")
        return self._stream

    def _rotate(self) -> None:
        """server.jsonl → .1 → .2 …, the oldest beyond `backups` dropped (as logging's RotatingFileHandler)."""
        for index in range(self.backups - 1, 0, -1):
            older = self.path.with_name(f"{self.path.name}.{index}")
            if older.exists():
                older.replace(self.path.with_name(f"{self.path.name}.{index + 1}"))
        self.path.replace(self.path.with_name(f"{self.path.name}.1"))

    def close(self) -> None:
        self.acquire()  # `handle` holds it around `emit`: a record is written whole or not at all
        try:
            self._closed = True
            if self._stream is not None:
                self._stream.close()
                self._stream = None
            self.writers.close()
        finally:
            self.release()
        super().close()


class _Ring(logging.Handler):
    def __init__(self, size: int) -> None:
        super().__init__()
        self.entries: deque[Entry] = deque(maxlen=size)
        self._entries_lock = threading.Lock()

    def emit(self, record: logging.LogRecord) -> None:
        entry = entry_of(record)
        with self._entries_lock:
            self.entries.append(entry)

    def newest_first(self) -> list[Entry]:
        with self._entries_lock:
            return list(reversed(self.entries))

    def drop(self, unwanted: Callable[[str], bool]) -> int:
        with self._entries_lock:
            kept = [entry for entry in self.entries if not unwanted(line_of(entry))]
            dropped = len(self.entries) - len(kept)
            self.entries.clear()
            self.entries.extend(kept)
        return dropped


class ServerLog:
    """One server's log sink. `install()` hooks it to the `segb` loggers; `read()` answers queries on it."""

    def __init__(self, path: Path | None, *, level: str = "INFO", max_bytes: int = 10_485_760, backups: int = 3):
        self.path = path
        self.level = level
        self.backups = backups
        if path is None:
            self.handler: logging.Handler = _Ring(RING_ENTRIES)
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            self.handler = _JsonLines(path, max_bytes=max_bytes, backups=backups)
        self.handler.setLevel(level)

    @classmethod
    def from_settings(cls, settings: Settings) -> ServerLog:
        return cls(
            settings.effective_server_log_file,
            level=settings.log_level,
            max_bytes=settings.server_log_max_bytes,
            backups=settings.server_log_backups,
        )

    @property
    def source(self) -> str:
        return "memory" if self.path is None else "file"

    @property
    def file(self) -> str | None:
        """The absolute path of the current log file; None when the log is kept in memory."""
        return None if self.path is None else str(self.path.resolve())

    def install(self) -> None:
        logger = logging.getLogger(ROOT_LOGGER)
        logger.addHandler(self.handler)
        # Without this, records under WARNING would be dropped before any handler saw them (the root
        # logger's default level); never raise a level someone lowered on purpose.
        if logger.level == logging.NOTSET or logger.level > self.handler.level:
            logger.setLevel(self.handler.level)

    def uninstall(self) -> None:
        logging.getLogger(ROOT_LOGGER).removeHandler(self.handler)
        self.handler.close()

    def forget(self, iris: Collection[str], texts: Collection[str]) -> int:
        """Remove every entry naming one of `iris` or quoting one of `texts` (an erased person's), from the file
        and its rotations; returns how many went. Every entry is read, a request's too (its path may name a
        person: `/ledger/{id}`, a mistyped route): the IRIs it names looked up in every spelling (as written, or
        percent-encoded in a URL, wholly or in part), and the path a request naming a person's IRI is logged as
        (`/humans/{iri}/human_maria`: the IRI's last segment), the texts searched for."""
        wanted = set(iris)
        in_paths = {form for iri in iris for segment in [_last_segment(iri)] for form in (segment, quote(segment))}
        needles = [form for text in texts if text for form in {text, json.dumps(text)[1:-1], quote(text, safe="")}]

        def quotes(line: str) -> bool:
            if any(_spelt(found) & wanted for found in _IRI.findall(line)):
                return True
            if any(segment in in_paths for segment in _HUMAN_PATH.findall(line)):
                return True
            return any(needle in line for needle in needles)

        return self._drop(quotes)

    def forget_before(self, cutoff: str) -> int:
        """Remove every entry written before `cutoff` (ISO 8601 UTC): retention."""

        def older(line: str) -> bool:
            try:
                return str(json.loads(line).get("time", "")) < cutoff
            except (ValueError, AttributeError):
                return False

        return self._drop(older)

    def _drop(self, unwanted: Callable[[str], bool]) -> int:
        if isinstance(self.handler, _Ring):
            return self.handler.drop(unwanted)
        assert isinstance(self.handler, _JsonLines) and self.path is not None
        dropped = 0
        # The handler's own lock keeps this process's writers out (the file lock, other processes').
        with _holding(self.handler), self.handler.writers.held():
            for index in range(self.backups + 1):
                path = self.path if index == 0 else self.path.with_name(f"{self.path.name}.{index}")
                try:
                    lines = path.read_bytes().decode("utf-8", errors="replace").splitlines(keepends=True)
                except FileNotFoundError:
                    continue
                kept = [line for line in lines if not unwanted(line)]
                if len(kept) == len(lines):
                    continue
                dropped += len(lines) - len(kept)
                # A new file replaces the old one: writers notice (another inode) and reopen; the old blocks are
                # the file system's, no longer any file's.
                fresh = path.with_name(path.name + ".forgetting")
                fresh.write_text("".join(kept), encoding="utf-8")
                fresh.replace(path)
        return dropped

    def read(self, limit: int, level: str = "DEBUG", contains: str | None = None) -> list[Entry]:
        """Up to `limit` entries at `level` or above whose text holds `contains` (any case), newest first, with
        the reference's field names too; blocking file reads, so call it off the event loop."""
        lowest = LEVELS.index(level)
        needle = contains.casefold() if contains else None
        found: list[Entry] = []
        for entry, raw in self._newest_first():
            if entry.get("level") not in LEVELS or LEVELS.index(entry["level"]) < lowest:
                continue
            if needle and needle not in " ".join(str(value) for value in entry.values()).casefold():
                continue
            found.append(with_reference_fields(entry, raw))
            if len(found) >= limit:
                break
        return found

    def _newest_first(self) -> Iterator[tuple[Entry, str]]:
        """Entries with the line each was read from."""
        if isinstance(self.handler, _Ring):
            yield from ((entry, line_of(entry)) for entry in self.handler.newest_first())
            return
        assert self.path is not None
        # The current file, then its rotated backups (.1 is the most recent), read only as far as needed.
        for index in range(self.backups + 1):
            path = self.path if index == 0 else self.path.with_name(f"{self.path.name}.{index}")
            try:
                lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
            except FileNotFoundError:
                continue
            yield from _parsed(reversed(lines))


def _last_segment(iri: str) -> str:
    return iri.rstrip("/").rsplit("/", 1)[-1]


def _spelt(found: str) -> set[str]:
    """An IRI found in a line, in the spellings it may stand for: as written, and percent-decoded as many times
    as it was encoded (a few)."""
    spellings = [found.rstrip(".,;)")]
    while len(spellings) < 4 and (decoded := unquote(spellings[-1])) != spellings[-1]:
        spellings.append(decoded)
    return set(spellings)


@contextmanager
def _holding(handler: logging.Handler) -> Iterator[None]:
    handler.acquire()
    try:
        yield
    finally:
        handler.release()


def _parsed(lines: Iterable[str]) -> Iterator[tuple[Entry, str]]:
    for line in lines:
        try:
            entry = json.loads(line)
        except ValueError:
            continue  # a line being written right now, or damaged by hand
        if isinstance(entry, dict) and all(isinstance(entry.get(key), str) for key in REQUIRED):
            yield entry, line
