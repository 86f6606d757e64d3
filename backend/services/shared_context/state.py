"""Where shared contexts live: the state database (backend/state), durable and transactional, one writer at a
time across every process sharing it."""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import astuple, dataclass, fields

from segb_server.backend.state.database import Database

STATE_FILE = "shared-context.sqlite3"

SCHEMA = """
CREATE TABLE IF NOT EXISTS contexts (
    seq            {serial},
    uri            TEXT NOT NULL UNIQUE,
    event_kind     TEXT NOT NULL,
    status         TEXT NOT NULL,
    observed_at    {real} NOT NULL,
    subject        TEXT,
    modality       TEXT,
    canonical_text TEXT,
    created_at     TEXT NOT NULL,
    updated_at     TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS contexts_by_time ON contexts (event_kind, observed_at);
CREATE TABLE IF NOT EXISTS observations (
    seq             {serial},
    context_uri     TEXT NOT NULL,
    observed_at     {real} NOT NULL,
    subject         TEXT,
    modality        TEXT,
    text            TEXT,
    observation_uri TEXT,
    robot_uri       TEXT,
    reported_by     TEXT,
    recorded_at     TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS observations_by_context ON observations (context_uri);
CREATE TABLE IF NOT EXISTS aliases (source TEXT PRIMARY KEY, target TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS cases (
    seq          {serial},
    case_id      TEXT NOT NULL UNIQUE,
    source_uri   TEXT NOT NULL,
    status       TEXT NOT NULL,
    candidates   TEXT NOT NULL,
    created_at   TEXT NOT NULL,
    decided_at   TEXT,
    selected_uri TEXT
);
CREATE TABLE IF NOT EXISTS rejected_pairs (
    source    TEXT NOT NULL,
    candidate TEXT NOT NULL,
    PRIMARY KEY (source, candidate)
);
CREATE TABLE IF NOT EXISTS withheld_observations (digest TEXT PRIMARY KEY);
"""
# withheld_observations: the digests (`observation_digest`) of the observations a person's erasure removed. A
# robot's resolver sends them again when it runs over its log again; they are then not recorded, as the journal
# holds back erased triples (docs/personal-data.md). Digests only: nothing of the person can be read back.


@dataclass
class Context:
    """One shared context. `seq` orders contexts by creation; `status` is active, ambiguous or merged."""

    seq: int | None
    uri: str
    event_kind: str
    status: str
    observed_at: float
    subject: str | None
    modality: str | None
    canonical_text: str | None
    created_at: str
    updated_at: str


@dataclass(frozen=True)
class ObservationRow:
    context_uri: str
    observed_at: float
    subject: str | None
    modality: str | None
    text: str | None
    observation_uri: str | None
    robot_uri: str | None
    reported_by: str | None  # the authenticated account that sent it
    recorded_at: str


@dataclass
class Case:
    """A review case: an ambiguous source context and its candidates, waiting for a person's decision."""

    case_id: str
    source_uri: str
    status: str
    candidates: list[dict[str, object]]
    created_at: str
    decided_at: str | None = None
    selected_uri: str | None = None


CONTEXT_COLUMNS = ", ".join(field.name for field in fields(Context))
OBSERVATION_COLUMNS = ", ".join(field.name for field in fields(ObservationRow))
CASE_COLUMNS = ", ".join(field.name for field in fields(Case))


def observation_digest(
    observed_at: float,
    subject: str | None,
    modality: str | None,
    text: str | None,
    observation_uri: str | None,
    robot_uri: str | None,
) -> str:
    """What makes an observation sent again the same one (who sent it aside): a SHA-256 of its fields."""
    fields = [repr(float(observed_at)), subject, modality, text, observation_uri, robot_uri]
    return hashlib.sha256(json.dumps(fields).encode("utf-8")).hexdigest()


def _placeholders(count: int) -> str:
    return ", ".join("?" for _ in range(count))


class ContextState:
    """Blocking access; `transaction()` serialises writers, even across processes and hosts."""

    def __init__(self, database: Database) -> None:
        self._db = database
        database.script(SCHEMA)

    @contextmanager
    def transaction(self) -> Iterator[ContextState]:
        with self._db.writing():
            yield self

    @contextmanager
    def snapshot(self) -> Iterator[ContextState]:
        """Consistent reads without taking the write lock of other processes."""
        with self._db.reading():
            yield self

    def close(self) -> None:
        self._db.close()

    def compact(self) -> None:
        self._db.compact()

    # --- contexts ------------------------------------------------------------------------------------

    def context(self, uri: str) -> Context | None:
        row = self._db.execute(f"SELECT {CONTEXT_COLUMNS} FROM contexts WHERE uri = ?", (uri,)).fetchone()
        return Context(*row) if row else None

    def contexts(self, uris: list[str]) -> list[Context]:
        found = (self.context(uri) for uri in dict.fromkeys(uris))
        return [context for context in found if context is not None]

    def unmerged_near(
        self, event_kind: str, earliest: float, latest: float, status: str | None = None
    ) -> list[Context]:
        """Active and ambiguous contexts of a kind observed in [earliest, latest], oldest created first."""
        sql = (
            f"SELECT {CONTEXT_COLUMNS} FROM contexts WHERE event_kind = ? AND observed_at BETWEEN ? AND ? "
            "AND status != 'merged'"
        )
        params: list[object] = [event_kind, earliest, latest]
        if status is not None:
            sql += " AND status = ?"
            params.append(status)
        return [Context(*row) for row in self._db.execute(sql + " ORDER BY seq", params)]

    def with_status(self, *statuses: str, newest_first: bool = False) -> list[Context]:
        order = "updated_at DESC, seq DESC" if newest_first else "seq"
        rows = self._db.execute(
            f"SELECT {CONTEXT_COLUMNS} FROM contexts WHERE status IN ({_placeholders(len(statuses))}) ORDER BY {order}",
            statuses,
        )
        return [Context(*row) for row in rows]

    def add_context(self, context: Context) -> None:
        values = astuple(context)[1:]  # seq is assigned by the database
        self._db.execute(
            f"INSERT INTO contexts ({CONTEXT_COLUMNS.removeprefix('seq, ')}) VALUES ({_placeholders(len(values))})",
            values,
        )

    def save_context(self, context: Context) -> None:
        self._db.execute(
            "UPDATE contexts SET status = ?, observed_at = ?, subject = ?, modality = ?, canonical_text = ?, "
            "updated_at = ? WHERE uri = ?",
            (
                context.status,
                context.observed_at,
                context.subject,
                context.modality,
                context.canonical_text,
                context.updated_at,
                context.uri,
            ),
        )

    def uri_taken(self, uri: str) -> bool:
        return self._db.execute("SELECT 1 FROM contexts WHERE uri = ?", (uri,)).fetchone() is not None

    def count_by_status(self) -> dict[str, int]:
        return dict(self._db.execute("SELECT status, COUNT(*) FROM contexts GROUP BY status").fetchall())

    # --- observations --------------------------------------------------------------------------------

    def add_observation(self, observation: ObservationRow) -> None:
        values = astuple(observation)
        self._db.execute(
            f"INSERT INTO observations ({OBSERVATION_COLUMNS}) VALUES ({_placeholders(len(values))})", values
        )

    def observations(self, context_uri: str) -> list[ObservationRow]:
        rows = self._db.execute(
            f"SELECT {OBSERVATION_COLUMNS} FROM observations WHERE context_uri = ? ORDER BY observed_at DESC, seq DESC",
            (context_uri,),
        )
        return [ObservationRow(*row) for row in rows]

    def move_observations(self, source: str, target: str) -> None:
        self._db.execute("UPDATE observations SET context_uri = ? WHERE context_uri = ?", (target, source))

    # --- aliases -------------------------------------------------------------------------------------

    def canonical(self, uri: str) -> str:
        row = self._db.execute("SELECT target FROM aliases WHERE source = ?", (uri,)).fetchone()
        return row[0] if row else uri

    def add_alias(self, source: str, target: str) -> None:
        # Kept flat: whatever pointed at the source now points at the target, so one lookup always suffices.
        self._db.execute("UPDATE aliases SET target = ? WHERE target = ?", (target, source))
        self._db.execute(
            "INSERT INTO aliases (source, target) VALUES (?, ?) "
            "ON CONFLICT (source) DO UPDATE SET target = excluded.target",
            (source, target),
        )

    def alias_count(self) -> int:
        return self._db.execute("SELECT COUNT(*) FROM aliases").fetchone()[0]

    # --- review cases --------------------------------------------------------------------------------

    def case(self, case_id: str) -> Case | None:
        row = self._db.execute(f"SELECT {CASE_COLUMNS} FROM cases WHERE case_id = ?", (case_id,)).fetchone()
        return _case(row) if row else None

    def pending_cases(self) -> list[Case]:
        rows = self._db.execute(f"SELECT {CASE_COLUMNS} FROM cases WHERE status = 'pending' ORDER BY seq DESC")
        return [_case(row) for row in rows]

    def pending_case_of(self, source_uri: str) -> Case | None:
        row = self._db.execute(
            f"SELECT {CASE_COLUMNS} FROM cases WHERE source_uri = ? AND status = 'pending'", (source_uri,)
        ).fetchone()
        return _case(row) if row else None

    def cases_of(self, source_uri: str) -> int:
        return self._db.execute("SELECT COUNT(*) FROM cases WHERE source_uri = ?", (source_uri,)).fetchone()[0]

    def save_case(self, case: Case) -> None:
        values = (*astuple(case)[:3], json.dumps(case.candidates), *astuple(case)[4:])
        self._db.execute(
            f"INSERT INTO cases ({CASE_COLUMNS}) VALUES ({_placeholders(len(values))}) "
            "ON CONFLICT (case_id) DO UPDATE SET status = excluded.status, candidates = excluded.candidates, "
            "decided_at = excluded.decided_at, selected_uri = excluded.selected_uri",
            values,
        )

    def reject_pair(self, source: str, candidate: str) -> None:
        self._db.execute(
            "INSERT INTO rejected_pairs (source, candidate) VALUES (?, ?) ON CONFLICT DO NOTHING", (source, candidate)
        )

    # --- forgetting ----------------------------------------------------------------------------------

    def forget(self, iris: set[str], texts: set[str], compared_texts: set[str]) -> int:
        """Remove every observation, context, alias and review case naming one of `iris` (a person erased, their
        shared events), every observation quoting one of `texts` and every context whose text is one of
        `compared_texts` (the same texts as contexts keep them); returns the rows removed. In the caller's
        transaction."""
        removed = 0
        for chunk in _chunks(sorted(iris)):
            marks = ", ".join(["?"] * len(chunk))
            self._withhold(_OBSERVATIONS_NAMING.format(marks), chunk * 3)
            for sql in _FORGET_BY_IRI:
                statement = sql.format(marks)
                removed += self._db.execute(statement, chunk * statement.count("(" + marks)).rowcount or 0
        # A case's candidates are JSON: read as text here (a LIKE pattern would need the IRI escaped for each SQL).
        naming = [
            case_id
            for case_id, candidates in self._db.execute("SELECT case_id, candidates FROM cases").fetchall()
            if not iris.isdisjoint(_QUOTED.findall(str(candidates)))
        ]
        for case_id in naming:
            removed += self._db.execute("DELETE FROM cases WHERE case_id = ?", (case_id,)).rowcount or 0
        for chunk in _chunks(sorted(texts)):
            self._withhold(_OBSERVATIONS_QUOTING.format(", ".join(["?"] * len(chunk))), chunk)
        for sql, quoted in ((_FORGET_OBSERVATIONS_BY_TEXT, texts), (_FORGET_CONTEXTS_BY_TEXT, compared_texts)):
            for chunk in _chunks(sorted(quoted)):
                removed += self._db.execute(sql.format(", ".join(["?"] * len(chunk))), chunk).rowcount or 0
        return removed

    def _withhold(self, selecting: str, values: list[str]) -> None:
        """Keep the digests of the observations `selecting` finds (before they are removed)."""
        for row in self._db.execute(selecting, values).fetchall():
            self._db.execute(
                "INSERT INTO withheld_observations (digest) VALUES (?) ON CONFLICT DO NOTHING",
                (observation_digest(*row),),
            )

    def withheld(self, digest: str) -> bool:
        """Whether an erasure removed the observation of this digest (`observation_digest`)."""
        return (
            self._db.execute("SELECT 1 FROM withheld_observations WHERE digest = ?", (digest,)).fetchone() is not None
        )

    def forget_before(self, cutoff: str) -> int:
        """Remove observations recorded before `cutoff` (ISO 8601 UTC), and contexts left with none."""
        removed = self._db.execute("DELETE FROM observations WHERE recorded_at < ?", (cutoff,)).rowcount or 0
        removed += (
            self._db.execute(
                "DELETE FROM contexts WHERE updated_at < ? AND uri NOT IN (SELECT context_uri FROM observations)",
                (cutoff,),
            ).rowcount
            or 0
        )
        return removed

    def rejected_candidates(self, source: str) -> set[str]:
        rows = self._db.execute("SELECT candidate FROM rejected_pairs WHERE source = ?", (source,))
        return {row[0] for row in rows}


# Everything that can name a person or one of their shared events (a case's candidates too, read in `forget`).
_FORGET_BY_IRI = (  # `{}`: the chunk's placeholders
    "DELETE FROM observations WHERE subject IN ({0}) OR context_uri IN ({0}) OR observation_uri IN ({0})",
    "DELETE FROM contexts WHERE subject IN ({0}) OR uri IN ({0})",
    "DELETE FROM aliases WHERE source IN ({0}) OR target IN ({0})",
    "DELETE FROM cases WHERE source_uri IN ({0}) OR selected_uri IN ({0})",
    "DELETE FROM rejected_pairs WHERE source IN ({0}) OR candidate IN ({0})",
)
_DIGESTED = "observed_at, subject, modality, text, observation_uri, robot_uri"  # `observation_digest`'s fields
_OBSERVATIONS_NAMING = (
    f"SELECT {_DIGESTED} FROM observations WHERE subject IN ({{0}}) OR context_uri IN ({{0}}) "
    "OR observation_uri IN ({0})"
)
_OBSERVATIONS_QUOTING = f"SELECT {_DIGESTED} FROM observations WHERE text IN ({{}})"
_FORGET_OBSERVATIONS_BY_TEXT = "DELETE FROM observations WHERE text IN ({})"  # as robots sent it
_FORGET_CONTEXTS_BY_TEXT = "DELETE FROM contexts WHERE canonical_text IN ({})"  # as scoring compares it
_QUOTED = re.compile(r'"([^"]+)"')  # every string of a case's candidates (JSON)
_CHUNK = 300  # values per statement: three IN lists of this stay under SQLite's 32,766 parameters


def _chunks(values: list[str]) -> list[list[str]]:
    return [values[start : start + _CHUNK] for start in range(0, len(values), _CHUNK)]


def _case(row: tuple[object, ...]) -> Case:
    case_id, source_uri, status, candidates, created_at, decided_at, selected_uri = row
    return Case(
        str(case_id),
        str(source_uri),
        str(status),
        json.loads(str(candidates)),
        str(created_at),
        decided_at,  # type: ignore[arg-type]
        selected_uri,  # type: ignore[arg-type]
    )
