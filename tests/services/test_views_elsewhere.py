"""The write path split between an API process and the views' own process (`Role.API`, `Role.VIEWS`), both in this
test process and joined as `segb serve` joins them: the views read the embedded store through its channel and the
journal up to the store's cursor; the API serves the reports from the views' files, queues nothing for views it does
not keep, and learns from the status file whether the views' process runs."""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import pytest
from pyoxigraph import RdfFormat

from segb_server.backend.config import Settings
from segb_server.backend.services.container import REQUIRED_QUERIES, KeptViews, Services, build_services, build_views
from segb_server.backend.services.ingest.payloads import RdfPayload
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.views.channel import ChannelStore, StoreChannel
from segb_server.backend.services.views.process import ViewsStatus
from segb_server.backend.services.writing.write_path import Role, WritePath
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.examples.receptionist import log_visit, receptionist
from tests.conftest import make_settings
from tests.support.robot_posts import RecordingGraph

T0 = datetime(2026, 5, 4, 9, 0, tzinfo=UTC)


@dataclass
class Split:
    settings: Settings
    api: Services
    views: KeptViews
    keeping: WritePath  # the views' own write path
    reader: ChannelStore


@pytest.fixture
def split() -> Iterator[Split]:
    settings = make_settings(store="oxigraph")
    store = OxigraphStore(settings.graph_uri, settings.data_dir / "oxigraph")
    channel = StoreChannel(store)
    api = build_services(settings, store, role=Role.API)
    api.writes.views_elsewhere = ViewsStatus(settings.data_dir)
    reader = ChannelStore(channel.address)
    views = build_views(settings, reader, Catalog(settings.sparql_dir, required=REQUIRED_QUERIES))
    keeping = WritePath.open(settings, reader, views.kept, views.housekeeping, Role.VIEWS)
    api.start()
    keeping.start()
    yield Split(settings, api, views, keeping, reader)
    keeping.close()
    views.close()
    reader.close()
    api.close()
    channel.close()
    store.close()


def post_visits(services: Services, first: int, count: int) -> tuple[int, set[str]]:
    """`count` visits of the receptionist robot as one post; its journal sequence and the visitors' messages."""
    logger = receptionist()
    graph = RecordingGraph()
    for triple in logger.graph:
        graph.add(triple)
    logger.graph = graph
    for index in range(first, first + count):
        log_visit(logger, index, T0 + timedelta(minutes=index))
    payload = RdfPayload(graph.serialize(format="nt").encode(), RdfFormat.N_TRIPLES, claimed_user=None)
    result = services.ingest.ingest(payload, actor="robot")
    return result.sequence, {f"Hello ARI, this is visit {index}." for index in range(first, first + count)}


def conversation_texts(services: Services) -> set[str]:
    table = services.reports.run("conversations", {}, 1000)
    assert table.served_from == "rows", "the conversations are not served from their rows"
    return {str(row["text"]) for row in table.rows}


def test_the_views_process_keeps_what_the_api_applies_and_the_api_serves_it(split: Split) -> None:
    sequence, said = post_visits(split.api, 0, 3)
    assert split.keeping.wait_viewed(sequence, 60), "the views' process did not keep the post"
    assert split.api.writes.wait_viewed(sequence, 10), "the API did not follow the views to the post"
    assert said <= conversation_texts(split.api)
    later, more = post_visits(split.api, 3, 2)
    assert split.api.writes.wait_viewed(later, 60)
    assert said | more <= conversation_texts(split.api)
    # The API process keeps no view: nothing it applied waited in a queue for views it does not keep.
    assert split.api.writes.keeper.most_queued_triples == 0
    assert split.api.writes.keeper.seen_terms is None and split.keeping.keeper.seen_terms is not None


def test_the_api_tells_whether_the_views_process_runs_from_its_status(split: Split) -> None:
    status = ViewsStatus(split.settings.data_dir)
    status.remove()
    time.sleep(ViewsStatus.READ_SECONDS)
    assert split.api.writes.views_failing()
    assert split.api.writes.views_error() == "the views' process is not running"
    status.write(outage=None, error=None)
    time.sleep(ViewsStatus.READ_SECONDS)
    assert not split.api.writes.views_failing() and split.api.writes.views_error() is None
    status.write(outage="the store does not answer", error="the store does not answer")
    time.sleep(ViewsStatus.READ_SECONDS)
    assert split.api.writes.views_failing()  # posts are not held for views that cannot move
    assert split.api.writes.views_error() == "the store does not answer"


def test_the_views_process_pulls_a_backlog_in_batches_without_rest(split: Split) -> None:
    """Posts made while nothing keeps the views (a views' process starting again) are caught up from the journal,
    the store's cursor read by the views' process itself."""
    split.keeping.close()
    sequences = [post_visits(split.api, 100 + 2 * index, 2)[0] for index in range(12)]
    assert split.keeping.keeper.rest_ratio == 0.0  # its own core: a rest would leave it idle
    keeping = WritePath.open(split.settings, split.reader, split.views.kept, split.views.housekeeping, Role.VIEWS)
    keeping.start()
    try:
        assert keeping.wait_viewed(sequences[-1], 60)
        assert split.api.writes.wait_viewed(sequences[-1], 10)
        assert {f"Hello ARI, this is visit {100 + index}." for index in range(24)} <= conversation_texts(split.api)
    finally:
        keeping.close()
    split.keeping = WritePath.open(split.settings, split.reader, split.views.kept, None, Role.VIEWS)
