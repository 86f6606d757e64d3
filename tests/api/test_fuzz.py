"""A bounded schemathesis run over the API's OpenAPI description: no input makes the server fail (5xx),
and answers match the documented schemas. Runs on a live server with authentication off."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import schemathesis
from hypothesis import HealthCheck, settings
from schemathesis.specs.openapi.checks import response_schema_conformance

from segb_server.backend.api.app import create_app
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import make_settings
from tests.support.live_server import LiveServer
from tests.support.scenarios import lobby


@pytest.fixture(scope="module")
def api_schema() -> Iterator[object]:
    store = OxigraphStore("http://amor-segb/events")
    with LiveServer(create_app(make_settings(), store=store)) as server:
        lobby().publish_all(server.url)
        yield schemathesis.openapi.from_url(f"{server.url}/openapi.json")
    store.close()


@schemathesis.serializer("application/sparql-query", "text/turtle", "application/n-triples")
def as_text(ctx, value) -> bytes:  # type: ignore[no-untyped-def]
    """Bodies that are plain text in some RDF or SPARQL syntax: whatever was generated, as UTF-8."""
    return value if isinstance(value, bytes) else str(value).encode("utf-8")


schema = schemathesis.pytest.from_fixture("api_schema")


# The event streams never end (a keep-alive every 15 s): they are tested in tests/api/test_streams.py.
@pytest.mark.slow  # a bounded random run over every operation, on a live server
@schema.exclude(path="/ttl/delete_all").exclude(path_regex="/stream$").parametrize()
@settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))
def test_no_input_breaks_the_server(case) -> None:  # type: ignore[no-untyped-def]
    response = case.call(timeout=30)
    assert response.status_code < 500, (
        f"{case.method} {case.formatted_path}: {response.status_code} {response.text[:300]}"
    )
    case.validate_response(response, checks=[response_schema_conformance])
