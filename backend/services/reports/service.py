"""Audit reports: the `.rq` files under `sparql/reports/`, run with bound filters, as tables of JSON values."""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

from segb_server.backend.services.csv_cells import spreadsheet_safe
from segb_server.backend.services.errors import Conflict, InvalidParameter, NotFound
from segb_server.backend.services.ops.result_cache import DataVersion, ResultCache
from segb_server.backend.services.reports.folder import FOLDER
from segb_server.backend.services.sparql.catalog import PARAMETER_VARIABLE_PREFIX, Catalog, CatalogQuery
from segb_server.backend.services.sparql.paging import evaluated_page
from segb_server.backend.services.values import JsonValue, json_value
from segb_server.backend.services.views.kept_queries.projection import KeptQueries
from segb_server.backend.services.views.kept_queries.rows import KeptRows
from segb_server.backend.services.writing.write_path import Lag
from segb_server.backend.store.base import Bindings, Store

DEFAULT_LIMIT = 1000
MAX_LIMIT = 10_000


def describe(query: CatalogQuery) -> dict[str, object]:
    """A report as the API lists it: name, title, description and its parameters (from the .rq header)."""
    return {
        "name": short_name(query),
        "title": query.title,
        "description": query.description,
        "parameters": [
            {"name": p.name, "type": p.type, "default": p.default, "description": p.help}
            for p in query.parameters.values()
        ],
        "href": f"/reports/{short_name(query)}",
        "max_limit": MAX_LIMIT,
    }


@dataclass(frozen=True)
class Behind:
    """Journal entries robots published that an answer does not include yet, and how long the oldest has waited."""

    entries: int
    seconds: float

    @classmethod
    def of(cls, lag: Lag, served_from: str) -> Behind | None:
        """Rows kept as the store changes lag by both the store's and the views' upkeep; a query's answer by the
        store's alone."""
        if served_from == "rows" and lag.views_entries:
            return cls(lag.apply_entries + lag.views_entries, round(lag.views_seconds, 3))
        if lag.apply_entries:
            return cls(lag.apply_entries, round(lag.apply_seconds, 3))
        return None


@dataclass(frozen=True)
class ReportTable:
    """One page of a report. `has_more` tells whether rows follow past `offset + limit`."""

    query: CatalogQuery
    columns: list[str]
    rows: list[dict[str, JsonValue]]
    limit: int
    offset: int
    has_more: bool
    next: str | None = None  # the cursor of the next page (`after=`), when rows are served from the report's rows
    served_from: str = "query"  # "rows" (kept current as the graph changes) or "query" (evaluated in full)
    last_event_id: int | None = None  # where `GET /reports/stream` resumes to hear of every later change
    behind: Behind | None = None  # how far these rows are behind what robots have published, when they are

    def as_json(self) -> dict[str, object]:
        described = describe(self.query)
        return {
            "report": described["name"],
            "title": self.query.title,
            "description": self.query.description,
            "parameters": described["parameters"],
            "max_limit": MAX_LIMIT,
            "columns": self.columns,
            "rows": self.rows,
            "limit": self.limit,
            "offset": self.offset,
            "has_more": self.has_more,
            "next": self.next,
            "served_from": self.served_from,
            "last_event_id": self.last_event_id,
            "behind": None if self.behind is None else {"entries": self.behind.entries, "seconds": self.behind.seconds},
        }

    def as_csv(self) -> str:
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=self.columns, extrasaction="ignore", lineterminator="\r\n")
        writer.writeheader()
        for row in self.rows:
            writer.writerow({column: _csv_cell(row.get(column)) for column in self.columns})
        return buffer.getvalue()


def _csv_cell(value: JsonValue) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return spreadsheet_safe(str(value))


class ReportService:
    """Reports served from their rows, kept current as the graph changes (services/views/kept_queries), or,
    while those are being built or for a report they cannot follow, by evaluating the report's query."""

    def __init__(
        self,
        catalog: Catalog,
        store: Store,
        cache: ResultCache | None = None,
        kept: KeptQueries | None = None,
        lag: Callable[[str | None], Lag] | None = None,
    ) -> None:
        """`lag(view)`: how far the store and a kept view (every view, for None) are behind the journal (the write
        path's), for answers that say how far behind they are."""
        self.catalog = catalog
        self.store = store
        self.cache = cache or ResultCache(DataVersion(), enabled=False)
        self._kept = kept
        self._lag = lag

    def change_log(self) -> KeptRows:
        """Where the live stream reads which keys' rows changed (and waits for changes); NotFound when no report
        is kept as rows."""
        if self._kept is None:
            raise NotFound("This server keeps no live reports.")
        return self._kept.rows

    def served_by_rows(self) -> dict[str, list[str]]:
        """Each kept query's name → the reports its rows serve (its own, and the presets sharing them)."""
        return self._kept.served() if self._kept is not None else {}

    def kept_queries(self) -> KeptQueries | None:
        """The reports' rows (None where no report is kept as rows)."""
        return self._kept

    def close(self) -> None:
        if self._kept is not None:
            self._kept.rows.close()

    def reports(self) -> list[CatalogQuery]:
        return self.catalog.under(FOLDER)

    def report(self, name: str) -> CatalogQuery:
        if "/" in name:
            raise NotFound(f"No report named '{name}'.")
        try:
            return self.catalog.get(f"{FOLDER}/{name}")
        except NotFound:
            raise NotFound(f"No report named '{name}'. Reports: {', '.join(self.names())}.") from None

    def names(self) -> list[str]:
        return [short_name(query) for query in self.reports()]

    def run(
        self, name: str, filters: Mapping[str, str | None], limit: int, offset: int = 0, after: str | None = None
    ) -> ReportTable:
        """Rows `offset`…`offset+limit` (or the `limit` rows after the cursor `after`) of a report, saying how far
        behind the log they are when they are; blocking (SQLite or store I/O), so call it off the event loop."""
        table = self._run(name, filters, limit, offset, after)
        if self._lag is None:
            return table
        kept = self._kept.reports.get(table.query.name) if self._kept is not None else None
        view = kept.name if kept is not None and table.served_from == "rows" else None
        return replace(table, behind=Behind.of(self._lag(view), table.served_from))

    def _run(
        self, name: str, filters: Mapping[str, str | None], limit: int, offset: int, after: str | None
    ) -> ReportTable:
        query = self.report(name)
        bindings = query.bindings(filters)
        if self._kept is not None:
            bound = {p: bindings[PARAMETER_VARIABLE_PREFIX + p] for p in query.parameters}
            page = self._kept.page(query.name, bound, limit, offset, after)
            if page is not None:
                columns = self._kept.columns(query.name)
                return ReportTable(
                    query, columns, page.rows, limit, offset, page.has_more, page.after, "rows", page.last_event_id
                )
        if after is not None:
            # Answering the first page instead would send a client paging by cursor round in circles.
            if self._kept is None or query.name not in self._kept.reports:
                raise InvalidParameter("after", f"report '{name}' is evaluated in full: page it with `offset`")
            raise Conflict(
                f"Report '{name}' is being rebuilt and cannot resume from a cursor now; start again from its first "
                "page (without `after`)."
            )
        key = ("report", name, tuple(sorted((k, str(v)) for k, v in bindings.items())), limit, offset)
        return self.cache.get(key, lambda: self._compute(query, bindings, limit, offset))

    def _compute(self, query: CatalogQuery, bindings: Bindings, limit: int, offset: int) -> ReportTable:
        # One row past the page tells whether another page exists without counting the whole result.
        result = evaluated_page(self.store, query.text, bindings, limit + 1, offset)
        rows = [{column: json_value(row.get(column)) for column in result.columns} for row in result.rows[:limit]]
        return ReportTable(query, result.columns, rows, limit, offset, len(result.rows) > limit)


def short_name(query: CatalogQuery) -> str:
    return query.name.removeprefix(FOLDER + "/")
