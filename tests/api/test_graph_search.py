"""A search draws what it found before the neighbours: with a small node limit the matches are still drawn."""

from __future__ import annotations

from tests.support.in_process import InProcess
from tests.support.scenarios import lobby


def test_a_search_draws_its_matches_before_their_neighbours(memory_api: InProcess) -> None:
    scenario = lobby()
    scenario.publish_all(memory_api.client)
    found = memory_api.get("/graph", params={"q": "driving test", "limit": 2}).json()
    message = str(scenario.iris["maria_1"])
    drawn = [node["id"] for node in found["nodes"]]
    hits = [iri for iri in drawn if iri in found["matches"]]
    assert message in hits and drawn[: len(hits)] == hits  # the matches first, before robots and humans
    assert found["truncated"] is True
