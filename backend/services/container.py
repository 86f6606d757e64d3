"""The set of services one running server uses, built once from the settings and the store."""

from __future__ import annotations

from dataclasses import dataclass

from segb_server.backend.config import Settings
from segb_server.backend.services.ingest.service import IngestService
from segb_server.backend.services.ops.ledger import LEDGER_FILE, Ledger
from segb_server.backend.services.ops.result_cache import OWNED_STORES, DataVersion, ResultCache
from segb_server.backend.services.ops.server_log import ServerLog
from segb_server.backend.services.shared_context.policy import Policy
from segb_server.backend.services.shared_context.service import SharedContextService
from segb_server.backend.services.shared_context.state import STATE_FILE
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.views.explain import ExplainService
from segb_server.backend.services.views.graph import GraphService
from segb_server.backend.services.views.reports import ReportService
from segb_server.backend.store.base import Store

# What the reports, the graph explorer and the explanations run; without them the server must not start.
REQUIRED_QUERIES = ("reports/", "graph/elements", "graph/resource-in", "graph/resource-out")


@dataclass
class Services:
    settings: Settings
    store: Store
    catalog: Catalog
    ingest: IngestService
    reports: ReportService
    graph: GraphService
    explain: ExplainService
    ledger: Ledger
    shared_context: SharedContextService
    server_log: ServerLog | None = None  # the API's own log; None where nothing serves it (the CLI, the demo)

    def close(self) -> None:
        self.ledger.close()
        self.shared_context.close()


def build_services(
    settings: Settings, store: Store, *, server_log: ServerLog | None = None, catalog: Catalog | None = None
) -> Services:
    catalog = catalog or Catalog(settings.sparql_dir, required=REQUIRED_QUERIES)
    version = DataVersion()
    cache = ResultCache(version, enabled=store.kind in OWNED_STORES)
    graph = GraphService(catalog, store, cache)
    # A memory store keeps its ledger in memory too: nothing of such a server is meant to be written.
    in_memory = settings.store == "memory"
    ledger = Ledger(None if in_memory else settings.data_dir / LEDGER_FILE)
    return Services(
        settings=settings,
        store=store,
        catalog=catalog,
        reports=ReportService(catalog, store, cache),
        graph=graph,
        explain=ExplainService(graph),
        ingest=IngestService(
            store,
            skolem_base=settings.effective_skolem_base,
            max_triples=settings.max_triples_per_post,
            version=version,
            ledger=ledger,
        ),
        ledger=ledger,
        shared_context=SharedContextService.open(
            Policy.from_settings(settings), None if in_memory else settings.data_dir / STATE_FILE
        ),
        server_log=server_log,
    )
