"""The set of services one running server uses, built once from the settings and the store."""

from __future__ import annotations

from dataclasses import dataclass

from segb_server.backend.config import Settings
from segb_server.backend.services.ingest.applier import Applier
from segb_server.backend.services.ingest.journal import JOURNAL_FILE, Journal
from segb_server.backend.services.ingest.service import IngestService
from segb_server.backend.services.ops.leadership import LOCK_FILE, Leadership, SharedLeadership
from segb_server.backend.services.ops.result_cache import DataVersion, ResultCache
from segb_server.backend.services.ops.server_log import ServerLog
from segb_server.backend.services.shared_context.policy import Policy
from segb_server.backend.services.shared_context.service import SharedContextService
from segb_server.backend.services.shared_context.state import STATE_FILE
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.sparql.runner import QueryRunner, query_runner
from segb_server.backend.services.views.explain import TOLD_LITERALS, ExplainService
from segb_server.backend.services.views.graph import GraphService
from segb_server.backend.services.views.graph_index import GraphIndex
from segb_server.backend.services.views.materialized.maintainer import ReportMaintainer
from segb_server.backend.services.views.materialized.rows import ReportRows
from segb_server.backend.services.views.projector import Projector
from segb_server.backend.services.views.reports import FOLDER as REPORTS_FOLDER
from segb_server.backend.services.views.reports import ReportService
from segb_server.backend.state.opening import open_state
from segb_server.backend.store.base import Store

# What the reports, the graph explorer and the explanations run; without them the server must not start.
REQUIRED_QUERIES = ("reports/", "graph/resource-in", "graph/resource-out")
# Stores written only through this server (the journal's applier), whose cached results a write invalidates.
OWNED_STORES = {"oxigraph", "memory"}
REPORTS_FILE = "reports.sqlite3"  # the reports' rows, kept current; rebuilt from the store when missing
GRAPH_FILE = "graph.sqlite3"  # the graph index, likewise


@dataclass
class Services:
    settings: Settings
    store: Store
    catalog: Catalog
    journal: Journal
    applier: Applier
    ingest: IngestService
    reports: ReportService
    graph: GraphService
    explain: ExplainService
    shared_context: SharedContextService
    queries: QueryRunner
    views: Projector  # keeps the reports' rows and the graph index current
    leadership: Leadership | SharedLeadership  # held by the one process (of all sharing the journal) that applies
    views_leadership: Leadership  # held by the one process (of several on this data directory) that keeps views
    server_log: ServerLog | None = None  # the API's own log; None where nothing serves it (the CLI, the demo)

    def start(self) -> None:
        """Start the background work of a serving API: applying the journal, keeping the views current (or, when
        another process on this data directory does that, following it)."""
        self.leadership.try_acquire()
        self.views_leadership.try_acquire()
        self.applier.start()
        self.views.start()

    def close(self) -> None:
        self.applier.stop()
        self.views.stop()
        self.graph.close()
        if self.reports.maintainer is not None:
            self.reports.maintainer.rows.close()
        self.queries.close()
        self.journal.close()
        self.shared_context.close()
        self.leadership.release()
        self.views_leadership.release()


def build_services(
    settings: Settings, store: Store, *, server_log: ServerLog | None = None, catalog: Catalog | None = None
) -> Services:
    """Everything a server needs; the applier's thread is not started (`services.applier.start()` does)."""
    catalog = catalog or Catalog(settings.sparql_dir, required=REQUIRED_QUERIES)
    # A memory store keeps its journal in memory too: nothing of such a server is meant to be written.
    in_memory = settings.store == "memory"
    journal = Journal(
        open_state(
            settings.state_url,
            None if in_memory else settings.data_dir / JOURNAL_FILE,
            writers="journal",
            sync_full=settings.journal_sync == "full",
        ),
        max_bytes=settings.journal_max_bytes,
    )
    # One process applies among all that share the journal; one per data directory keeps its views.
    views_leadership = Leadership(None if in_memory else settings.data_dir / LOCK_FILE)
    leadership = SharedLeadership(settings.state_url, "applier") if settings.state_url else views_leadership
    applier = Applier(journal, store, batch_triples=settings.apply_batch_triples, leadership=leadership)
    version = DataVersion()
    applier.on_applied(lambda _step: version.bump())  # whatever the applier writes invalidates cached results
    cache = ResultCache(version, enabled=store.kind in OWNED_STORES)
    maintainer = ReportMaintainer(store, ReportRows(None if in_memory else settings.data_dir / REPORTS_FILE))
    index = GraphIndex(store, None if in_memory else settings.data_dir / GRAPH_FILE, detail_literals=TOLD_LITERALS)
    if settings.keep_views:
        for query in catalog.under(REPORTS_FOLDER):
            maintainer.add(query)
    # Views off: nothing kept, and the rows kept before stay as they are for when they are on again.
    kept = [*maintainer.projections(), index] if settings.keep_views else []
    housekeeping = maintainer.drop_unkept if settings.keep_views else None
    views = Projector(store, journal, kept, views_leadership, applier, housekeeping)
    applier.on_applied(views.on_applied)
    graph = GraphService(
        catalog,
        store,
        index,
        wait_ready=lambda timeout: views.wait_for(0, timeout),
        pending=lambda limit: views.pending(applier.applied, limit),
    )
    return Services(
        settings=settings,
        store=store,
        catalog=catalog,
        journal=journal,
        applier=applier,
        ingest=IngestService(
            journal,
            applier,
            skolem_base=settings.effective_skolem_base,
            max_triples=settings.max_triples_per_post,
            ack=settings.effective_ingest_ack,
            apply_timeout=settings.ingest_apply_timeout_seconds,
            max_backlog=settings.journal_max_backlog,
        ),
        reports=ReportService(catalog, store, cache, maintainer),
        graph=graph,
        explain=ExplainService(graph),
        shared_context=SharedContextService.open(
            Policy.from_settings(settings),
            open_state(settings.state_url, None if in_memory else settings.data_dir / STATE_FILE, writers="contexts"),
        ),
        queries=query_runner(
            store,
            version,
            workers=settings.sparql_workers,
            max_memory_bytes=settings.sparql_max_memory_bytes,
            snapshots=None if in_memory else settings.data_dir / "snapshots",
        ),
        views=views,
        leadership=leadership,
        views_leadership=views_leadership,
        server_log=server_log,
    )
