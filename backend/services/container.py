"""The set of services one running server uses, built once from the settings and the store."""

from __future__ import annotations

from dataclasses import dataclass

from backend.config import Settings
from backend.services.catalog import Catalog
from backend.services.ingest import IngestService
from backend.services.reports import ReportService
from backend.store.base import Store


@dataclass
class Services:
    settings: Settings
    store: Store
    catalog: Catalog
    ingest: IngestService
    reports: ReportService


def build_services(settings: Settings, store: Store) -> Services:
    catalog = Catalog(settings.sparql_dir)
    return Services(
        settings=settings,
        store=store,
        catalog=catalog,
        reports=ReportService(catalog, store),
        ingest=IngestService(
            store, skolem_base=settings.effective_skolem_base, max_triples=settings.max_triples_per_post
        ),
    )
