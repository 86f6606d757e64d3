"""The set of services one running server uses, built once from the settings and the store."""

from __future__ import annotations

from dataclasses import dataclass

from segb_server.backend.config import Settings
from segb_server.backend.services.ingest.applier import Applier
from segb_server.backend.services.ingest.journal import JOURNAL_FILE, Journal
from segb_server.backend.services.ingest.service import IngestService
from segb_server.backend.services.ops.result_cache import DataVersion, ResultCache
from segb_server.backend.services.ops.server_log import ServerLog
from segb_server.backend.services.shared_context.policy import Policy
from segb_server.backend.services.shared_context.service import SharedContextService
from segb_server.backend.services.shared_context.state import STATE_FILE
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.sparql.runner import QueryRunner, query_runner
from segb_server.backend.services.views.explain import ExplainService
from segb_server.backend.services.views.graph import GraphService
from segb_server.backend.services.views.reports import ReportService
from segb_server.backend.store.base import Store

# What the reports, the graph explorer and the explanations run; without them the server must not start.
REQUIRED_QUERIES = ("reports/", "graph/elements", "graph/resource-in", "graph/resource-out")
# Stores written only through this server (the journal's applier), whose cached results a write invalidates.
OWNED_STORES = {"oxigraph", "memory"}


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
    server_log: ServerLog | None = None  # the API's own log; None where nothing serves it (the CLI, the demo)

    def close(self) -> None:
        self.applier.stop()
        self.queries.close()
        self.journal.close()
        self.shared_context.close()


def build_services(
    settings: Settings, store: Store, *, server_log: ServerLog | None = None, catalog: Catalog | None = None
) -> Services:
    """Everything a server needs; the applier's thread is not started (`services.applier.start()` does)."""
    catalog = catalog or Catalog(settings.sparql_dir, required=REQUIRED_QUERIES)
    # A memory store keeps its journal in memory too: nothing of such a server is meant to be written.
    in_memory = settings.store == "memory"
    journal = Journal(
        None if in_memory else settings.data_dir / JOURNAL_FILE,
        sync_full=settings.journal_sync == "full",
        max_bytes=settings.journal_max_bytes,
    )
    applier = Applier(journal, store, batch_triples=settings.apply_batch_triples)
    version = DataVersion()
    applier.on_applied(lambda _step: version.bump())  # whatever the applier writes invalidates cached results
    cache = ResultCache(version, enabled=store.kind in OWNED_STORES)
    graph = GraphService(catalog, store, cache)
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
        reports=ReportService(catalog, store, cache),
        graph=graph,
        explain=ExplainService(graph),
        shared_context=SharedContextService.open(
            Policy.from_settings(settings), None if in_memory else settings.data_dir / STATE_FILE
        ),
        queries=query_runner(
            store,
            version,
            workers=settings.sparql_workers,
            max_memory_bytes=settings.sparql_max_memory_bytes,
            snapshots=None if in_memory else settings.data_dir / "snapshots",
        ),
        server_log=server_log,
    )
