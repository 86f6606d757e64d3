"""The set of services one running server uses, built once from the settings and the store."""

from __future__ import annotations

from dataclasses import dataclass

from segb_server.backend.config import Settings
from segb_server.backend.services.evidence.bundle import WINDOW, EvidenceService
from segb_server.backend.services.evidence.key import ServerKey
from segb_server.backend.services.explain.service import TOLD_LITERALS, ExplainService
from segb_server.backend.services.graph.service import GraphService
from segb_server.backend.services.ingest.service import IngestService
from segb_server.backend.services.ops.result_cache import DataVersion, ResultCache
from segb_server.backend.services.ops.server_log import ServerLog
from segb_server.backend.services.people.erasure import RULE as ERASURE_RULE
from segb_server.backend.services.people.erasure import ErasureService
from segb_server.backend.services.people.export import STORY, PersonExport
from segb_server.backend.services.people.mentions import RULE as MENTIONS_RULE
from segb_server.backend.services.people.places import forgetting
from segb_server.backend.services.people.retention import Retention
from segb_server.backend.services.reports.folder import FOLDER as REPORTS_FOLDER
from segb_server.backend.services.reports.service import ReportService
from segb_server.backend.services.rules.catalog import RuleCatalog
from segb_server.backend.services.rules.service import FindingsService
from segb_server.backend.services.rules.shapes import ShapeRule
from segb_server.backend.services.shared_context.policy import Policy
from segb_server.backend.services.shared_context.service import SharedContextService
from segb_server.backend.services.shared_context.state import STATE_FILE
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.sparql.runner import QueryRunner, query_runner
from segb_server.backend.services.timeline.findings_source import FindingSource
from segb_server.backend.services.timeline.kinds import FOLDER as TIMELINE_FOLDER
from segb_server.backend.services.timeline.kinds import KINDS, query_name
from segb_server.backend.services.timeline.service import TimelineService
from segb_server.backend.services.timeline.sources import KeptSource
from segb_server.backend.services.views.graph_index import GraphIndex
from segb_server.backend.services.views.kept_queries.projection import KeptQueries
from segb_server.backend.services.views.kept_queries.rows import KeptRows
from segb_server.backend.services.views.pace import ViewsPace
from segb_server.backend.services.views.seen_terms import SEEN_TERMS_FILE
from segb_server.backend.services.views.shape_view import ShapeFindings
from segb_server.backend.services.views.view import KeptView
from segb_server.backend.services.writing.write_path import Role, WritePath
from segb_server.backend.state.opening import open_state
from segb_server.backend.store.base import Store

# What the reports, the timeline, the graph explorer, the explanations and people's data run; without them the
# server must not start.
REQUIRED_QUERIES = (
    "reports/",
    f"{TIMELINE_FOLDER}/",
    "graph/resource-in",
    "graph/resource-out",
    ERASURE_RULE,
    MENTIONS_RULE,
    STORY,
    WINDOW,
)
# Stores written only through this server (the journal's applier), whose cached results a write invalidates.
OWNED_STORES = {"oxigraph", "memory"}
REPORTS_FILE = "reports.sqlite3"  # the reports' rows, kept current; rebuilt from the store when missing
GRAPH_FILE = "graph.sqlite3"  # the graph index, likewise
FINDINGS_FILE = "findings.sqlite3"  # the SPARQL rules' findings, kept as the reports' rows are
SHAPE_FINDINGS_FILE = "shape-findings.sqlite3"  # the SHACL rules' findings
TIMELINE_FILE = "timeline.sqlite3"  # the timeline's rows, one table per kind, likewise
# Every file the views keep beside the store (each with its -wal), the registry of the IRIs the store holds included.
VIEW_FILES = (REPORTS_FILE, GRAPH_FILE, FINDINGS_FILE, SHAPE_FINDINGS_FILE, TIMELINE_FILE, SEEN_TERMS_FILE)


@dataclass
class Services:
    settings: Settings
    store: Store
    catalog: Catalog
    writes: WritePath  # journal → store → views, and which process does what
    ingest: IngestService
    views_pace: ViewsPace  # how long a post's answer waits for the views
    reports: ReportService
    findings: FindingsService
    timeline: TimelineService
    graph: GraphService
    explain: ExplainService
    shared_context: SharedContextService
    queries: QueryRunner
    timeline_rows: KeptQueries  # the timeline's kinds kept as rows (its live stream reads their changes)
    erasure: ErasureService
    people_export: PersonExport
    evidence: EvidenceService
    retention: Retention | None = None  # with RETENTION_DAYS: erases what is past it, on schedule
    server_log: ServerLog | None = None  # the API's own log; None where nothing serves it (the CLI, the demo)

    def start(self) -> None:
        """Start the background work of a serving API: applying the journal, keeping the views current (or, when
        another process on this data directory does that, following it)."""
        self.writes.start()
        if self.retention is not None:
            self.retention.start()

    def close(self) -> None:
        if self.retention is not None:
            self.retention.stop()
        self.writes.close()
        self.graph.close()
        self.reports.close()
        if self.findings.kept is not None:
            self.findings.kept.rows.close()
        if self.findings.shapes is not None:
            self.findings.shapes.close()
        self.timeline_rows.rows.close()
        self.queries.close()
        self.shared_context.close()


@dataclass
class KeptViews:
    """The views of the catalog's reports, the timeline's kinds, the rules and the graph: what reads them, and
    (with KEEP_VIEWS) what the write path keeps current. Built alike wherever they are read or kept."""

    reports: KeptQueries
    timeline: KeptQueries
    timeline_sources: list[KeptSource]
    findings: KeptQueries
    shapes: ShapeFindings | None  # None without KEEP_VIEWS: shapes are then checked in full
    shape_rules: dict[str, ShapeRule]
    rules: RuleCatalog
    graph: GraphIndex
    kept: list[KeptView]  # what the write path keeps current (none without KEEP_VIEWS)

    def housekeeping(self) -> None:
        """Drop what the views' storage holds for reports, kinds or rules no longer kept."""
        self.reports.drop_unkept()
        self.findings.drop_unkept()
        self.timeline.drop_unkept()

    def close(self) -> None:
        self.graph.close()
        self.reports.rows.close()
        self.findings.rows.close()
        if self.shapes is not None:
            self.shapes.close()
        self.timeline.rows.close()


def build_views(settings: Settings, store: Store, catalog: Catalog) -> KeptViews:
    """The views, as files in the data directory (temporary ones for a memory store)."""
    folder = None if settings.store == "memory" else settings.data_dir  # views of a memory store: temporary files
    kept_reports = KeptQueries(store, KeptRows(folder and folder / REPORTS_FILE))
    index = GraphIndex(store, folder and folder / GRAPH_FILE, detail_literals=TOLD_LITERALS)
    rules = RuleCatalog(settings.rules_dir)
    shape_rules = {rule.id: ShapeRule(rule) for rule in rules.shapes()}
    kept_findings = KeptQueries(store, KeptRows(folder and folder / FINDINGS_FILE))
    kept_timeline = KeptQueries(store, KeptRows(folder and folder / TIMELINE_FILE))
    timeline = timeline_sources(catalog, store, kept_timeline)
    if not settings.keep_views:  # nothing kept; the rows kept before stay as they are for when views are on again
        return KeptViews(kept_reports, kept_timeline, timeline, kept_findings, None, shape_rules, rules, index, [])
    shape_findings = ShapeFindings(
        store, list(shape_rules.values()), folder and folder / SHAPE_FINDINGS_FILE, kept_findings.rows.changed
    )
    for query in catalog.under(REPORTS_FOLDER):
        kept_reports.add(query)
    for rule in rules.sparql():
        assert rule.query is not None
        kept_findings.add(rule.query)
    for source in timeline:
        kept_timeline.add(source.query)
    kept: list[KeptView] = [
        *kept_reports.views(),
        *kept_timeline.views(),
        index,
        *kept_findings.views(),
        shape_findings,
    ]
    return KeptViews(
        kept_reports, kept_timeline, timeline, kept_findings, shape_findings, shape_rules, rules, index, kept
    )


def build_services(
    settings: Settings,
    store: Store,
    *,
    server_log: ServerLog | None = None,
    catalog: Catalog | None = None,
    role: Role = Role.WHOLE,
) -> Services:
    """Everything a server needs; nothing is started (`services.start()` starts the write path's threads).
    `role`: Role.API where the views are kept by a process of their own, which this one follows."""
    catalog = catalog or Catalog(settings.sparql_dir, required=REQUIRED_QUERIES)
    folder = None if settings.store == "memory" else settings.data_dir
    views = build_views(settings, store, catalog)
    kept_reports, kept_findings, kept_timeline = views.reports, views.findings, views.timeline
    shape_findings, index, timeline = views.shapes, views.graph, views.timeline_sources
    writes = WritePath.open(settings, store, views.kept, views.housekeeping if views.kept else None, role)
    version = DataVersion()
    writes.on_applied(lambda _step: version.bump())  # whatever the applier writes invalidates cached results
    cache = ResultCache(version, enabled=store.kind in OWNED_STORES)
    findings = FindingsService(
        views.rules, store, kept_findings if settings.keep_views else None, shape_findings, views.shape_rules
    )
    graph = GraphService(
        catalog,
        store,
        index,
        wait_ready=lambda timeout: writes.wait_viewed(0, timeout),
        pending=lambda limit: writes.on_the_way(limit, index.name),
    )
    shared_context = SharedContextService.open(
        Policy.from_settings(settings),
        open_state(settings.state_url, folder and folder / STATE_FILE, writers="contexts"),
    )
    queries = query_runner(
        store,
        version,
        workers=settings.sparql_workers,
        max_memory_bytes=settings.sparql_max_memory_bytes,
        snapshots=folder and folder / "snapshots",
    )
    view_files = [folder / name for name in VIEW_FILES] if folder else []
    places = forgetting(writes.journal, shared_context, queries, server_log, view_files)
    erasure = ErasureService(store, catalog.get(ERASURE_RULE), writes, places, mentions_rule=catalog.get(MENTIONS_RULE))
    return Services(
        settings=settings,
        store=store,
        catalog=catalog,
        writes=writes,
        ingest=IngestService(
            writes,
            skolem_base=settings.effective_skolem_base,
            max_triples=settings.max_triples_per_post,
            ack=settings.effective_ingest_ack,
            apply_timeout=settings.ingest_apply_timeout_seconds,
            max_backlog=settings.journal_max_backlog,
        ),
        views_pace=ViewsPace(writes, settings.effective_views_max_lag_seconds, settings.views_max_hold_seconds),
        reports=ReportService(catalog, store, cache, kept_reports, lag=writes.view_lag),
        findings=findings,
        timeline=TimelineService([*timeline, FindingSource(findings)], kept_timeline.rows.last_change),
        graph=graph,
        explain=ExplainService(graph),
        shared_context=shared_context,
        queries=queries,
        erasure=erasure,
        people_export=PersonExport(store, erasure, catalog.get(STORY)),
        evidence=EvidenceService(
            store, writes.journal, catalog.get(WINDOW), ServerKey.at(folder) if folder else ServerKey.in_memory()
        ),
        timeline_rows=kept_timeline,
        server_log=server_log,
        retention=None
        if settings.retention_days is None
        else Retention(
            erasure,
            settings.retention_days,
            settings.retention_check_seconds,
            lambda: writes.apply_leadership.held,
        ),
    )


def timeline_sources(catalog: Catalog, store: Store, kept: KeptQueries) -> list[KeptSource]:
    """One source per kind of event that has a query (`sparql/timeline/<kind>.rq`)."""
    names = {query.name for query in catalog.under(TIMELINE_FOLDER)}
    return [KeptSource(kind, catalog.get(query_name(kind)), kept, store) for kind in KINDS if query_name(kind) in names]
