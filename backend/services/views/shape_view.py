"""The findings of the SHACL rules, kept current as robots publish (a `KeptView` of the views' keeper).

Built once by checking every target of every shape; then, for each batch of applied journal steps, the nodes
the batch's new triples name (as subject or object) that are targets of a shape are checked again, and their
findings replaced. A shape looks only at a focus node's own statements (see shapes.py), and the triples that
can change those name the node as their subject, so this keeps exactly what a full check would find. Stored in
its own SQLite file, read page by page per rule in time order (keyset paging), filtered by robot and time.
The checking itself is `shape_checks.py`.
"""

from __future__ import annotations

import hashlib
import logging
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import orjson

from segb_server.backend.services.rules.shapes import ShapeRule, generated_by_newly_performed
from segb_server.backend.services.values import JsonValue
from segb_server.backend.services.views.cursors import cursor_of, findings_cursor
from segb_server.backend.services.views.database import ViewDatabase
from segb_server.backend.services.views.delta import Delta
from segb_server.backend.services.views.kept_queries.encoding import instant
from segb_server.backend.services.views.shape_checks import Found, check_rules, check_shapes
from segb_server.backend.services.views.signal import ChangeSignal
from segb_server.backend.store.base import Store, Term

logger = logging.getLogger("segb.rules")

VERSION = "2"  # bump when the stored layout changes: the findings are then built again
CHANGES_KEPT = 20_000
SCHEMA = [
    "CREATE TABLE IF NOT EXISTS shape_findings (rule TEXT, unit TEXT, n INTEGER, ord TEXT, time TEXT, robot TEXT, "
    "row TEXT, PRIMARY KEY (rule, unit, n))",
    "CREATE INDEX IF NOT EXISTS shape_findings_ord ON shape_findings (rule, ord, unit, n)",
    "CREATE INDEX IF NOT EXISTS shape_findings_robot ON shape_findings (rule, robot, ord, unit, n)",
    "CREATE TABLE IF NOT EXISTS shape_state (name TEXT PRIMARY KEY, fingerprint TEXT, through INTEGER)",
    "CREATE TABLE IF NOT EXISTS shape_changes (seq INTEGER PRIMARY KEY AUTOINCREMENT, rule TEXT, unit TEXT, "
    "through INTEGER)",
]
NAME = "shape-findings"
Record = tuple[str, str | None, str | None, str]  # sort key, time, robot, the finding as JSON


@dataclass(frozen=True)
class ShapePage:
    rows: list[dict[str, JsonValue]]
    has_more: bool
    after: str | None


class ShapeFindings:
    """Every SHACL rule's findings, one table, replaced node by node."""

    name = NAME

    def __init__(
        self, store: Store, rules: list[ShapeRule], path: Path | None, changed: ChangeSignal | None = None
    ) -> None:
        """`changed`: the signal to wake live readers with (shared with the SPARQL rules' rows: one stream)."""
        self.store = store
        self.rules = rules
        self.db = ViewDatabase(path, SCHEMA)
        self.changed = changed or ChangeSignal()
        self.ready = False
        texts = [VERSION, *SCHEMA, *(f"{rule.rule.id}\n{rule.rule.shapes}" for rule in rules)]
        self.fingerprint = hashlib.sha256("\n".join(texts).encode()).hexdigest()

    # --- KeptView ------------------------------------------------------------------------------------

    def stored_through(self) -> int | None:
        return self.follow()

    def follow(self) -> int | None:
        row = (
            self.db.reader().execute("SELECT fingerprint, through FROM shape_state WHERE name = ?", (NAME,)).fetchone()
        )
        return row[1] if row and row[0] == self.fingerprint else None

    def prepared(self) -> None:
        pass  # pages are read from the table as it is

    def build(self, through: int) -> None:
        checked = {rule.rule.id: self._check(rule, None) for rule in self.rules}
        with self.db.writing() as connection:
            connection.execute("DELETE FROM shape_findings")
            for rule_id, (units, rows) in checked.items():
                self._replace(connection, rule_id, units, rows, through, announce=False)
            self._set_state(connection, through)
        logger.info("SHACL rules checked: %d findings", sum(len(rows) for _, rows in checked.values()))

    def update(self, delta: Delta, through: int) -> None:
        checked: dict[str, tuple[set[str], dict[str, list[Record]]]] = {}
        if delta:
            # Every rule's targets among the nodes the batch names, then their statements read once for all.
            named = _named_nodes(delta) | generated_by_newly_performed(self.store, delta)
            found = check_rules(self.rules, self.store, named, delta)
            checked = {rule_id: (units, self._records(rows)) for rule_id, (units, rows) in found.items()}
        changed = False
        with self.db.writing() as connection:
            for rule_id, (units, rows) in checked.items():
                if units:
                    self._replace(connection, rule_id, units, rows, through, announce=True)
                    changed = True
            if changed:
                connection.execute(
                    "DELETE FROM shape_changes WHERE seq <= (SELECT MAX(seq) FROM shape_changes) - ?", (CHANGES_KEPT,)
                )
            self._set_state(connection, through)
        if changed:
            self.changed.notify()

    def clear(self, through: int) -> None:
        with self.db.writing() as connection:
            connection.execute("DELETE FROM shape_findings")
            self._set_state(connection, through)

    def forget_erased(self) -> None:
        """An erasure: the change log names the nodes it concerned (erased ones among them)."""
        with self.db.writing() as connection:
            connection.execute("DELETE FROM shape_changes")

    # --- checking ------------------------------------------------------------------------------------

    def _check(self, rule: ShapeRule, named: set[str] | None) -> tuple[set[str], dict[str, list[Record]]]:
        """The nodes checked (every target of a shape among `named`, or all) and their findings as records."""
        units, found = check_shapes(rule, self.store, named)
        return units, self._records(found)

    @staticmethod
    def _records(found: dict[str, list[Found]]) -> dict[str, list[Record]]:
        return {
            unit: [(order, moment, robot, orjson.dumps(row).decode()) for order, moment, robot, row in rows]
            for unit, rows in found.items()
        }

    def _replace(
        self,
        connection: object,
        rule_id: str,
        units: Iterable[str],
        rows: dict[str, list[Record]],
        through: int,
        *,
        announce: bool,
    ) -> None:
        units = sorted(units)
        execute = connection.execute  # type: ignore[attr-defined]
        for start in range(0, len(units), 500):
            chunk = units[start : start + 500]
            marks = ", ".join("?" * len(chunk))
            execute(f"DELETE FROM shape_findings WHERE rule = ? AND unit IN ({marks})", [rule_id, *chunk])
        records = [(rule_id, unit, n, *record) for unit in units for n, record in enumerate(rows.get(unit, []))]
        connection.executemany("INSERT INTO shape_findings VALUES (?, ?, ?, ?, ?, ?, ?)", records)  # type: ignore[attr-defined]
        if announce:
            connection.executemany(  # type: ignore[attr-defined]
                "INSERT INTO shape_changes (rule, unit, through) VALUES (?, ?, ?)",
                [(rule_id, unit, through) for unit in units],
            )

    def _set_state(self, connection: object, through: int) -> None:
        connection.execute(  # type: ignore[attr-defined]
            "INSERT INTO shape_state VALUES (?, ?, ?) ON CONFLICT (name) DO UPDATE SET "
            "fingerprint = excluded.fingerprint, through = excluded.through",
            (NAME, self.fingerprint, through),
        )

    # --- reading -------------------------------------------------------------------------------------

    def page(self, rule_id: str, robot: str | None, since: Term | None, until: Term | None, limit: int,
             after: str | None) -> ShapePage:  # fmt: skip
        """One rule's findings in time order, after the cursor `after`."""
        where: list[str] = ["rule = ?"]
        arguments: list[object] = [rule_id]
        if robot is not None:
            where.append("robot = ?")
            arguments.append(robot)
        if since is not None:
            where.append("time >= ?")
            arguments.append(instant(since) or "")
        if until is not None:
            where.append("time <= ?")
            arguments.append(instant(until) or "")
        if after is not None:
            where.append("(ord, unit, n) > (?, ?, ?)")
            arguments += findings_cursor(after)
        found = (
            self.db.reader()
            .execute(
                f"SELECT ord, unit, n, row FROM shape_findings WHERE {' AND '.join(where)} ORDER BY ord, unit, n "
                "LIMIT ?",
                [*arguments, limit + 1],
            )
            .fetchall()
        )
        kept = found[:limit]
        has_more = len(found) > limit
        last = cursor_of(*kept[-1][:3]) if kept and has_more else None
        return ShapePage([orjson.loads(row[3]) for row in kept], has_more, last)

    def count(self, rule_id: str, robot: str | None, since: Term | None, until: Term | None) -> int:
        where: list[str] = ["rule = ?"]
        arguments: list[object] = [rule_id]
        for column, op, value in (("robot", "=", robot), ("time", ">=", since), ("time", "<=", until)):
            if value is not None:
                where.append(f"{column} {op} ?")
                arguments.append(value if isinstance(value, str) else (instant(value) or ""))
        query = f"SELECT COUNT(*) FROM shape_findings WHERE {' AND '.join(where)}"
        return int(self.db.reader().execute(query, arguments).fetchone()[0])

    def unit_rows(self, rule_id: str, units: list[str]) -> list[dict[str, JsonValue]]:
        """The findings of one rule about these nodes (N-Triples texts)."""
        if not units:
            return []
        marks = ", ".join("?" * len(units))
        found = self.db.reader().execute(
            f"SELECT row FROM shape_findings WHERE rule = ? AND unit IN ({marks}) ORDER BY ord, unit, n",
            [rule_id, *units],
        )
        return [orjson.loads(row[0]) for row in found.fetchall()]

    def last_change(self) -> int:
        return int(self.db.reader().execute("SELECT COALESCE(MAX(seq), 0) FROM shape_changes").fetchone()[0])

    def changes_since(self, seq: int, limit: int = 1000) -> list[tuple[int, str, str]]:
        return (
            self.db.reader()
            .execute("SELECT seq, rule, unit FROM shape_changes WHERE seq > ? ORDER BY seq LIMIT ?", (seq, limit))
            .fetchall()
        )

    def close(self) -> None:
        self.db.close()


def _named_nodes(delta: Delta) -> set[str]:
    """The IRIs the batch's triples name, as subject or object."""
    named: set[str] = set()
    for predicate in delta.predicates():
        for fact in delta.with_predicate(predicate):
            named.add(fact.subject_text)
            if fact.object_text.startswith("<"):
                named.add(fact.object_text)
    return named
