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


TURTLE = """
@prefix ex: <https://example.org/segb/> .
@prefix foaf: <http://xmlns.com/foaf/0.1/> .
@prefix oro: <http://kb.openrobots.org#> .
@prefix prov: <http://www.w3.org/ns/prov#> .
@prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
@prefix xsd: <http://www.w3.org/2001/XMLSchema#> .
ex:zoe a oro:Human ; foaf:firstName "ZOË STRAßE" .
ex:ana a oro:Human ; foaf:firstName "Ana Reyes" .
ex:zoned a prov:Activity ; rdfs:label "zoned" ; prov:startedAtTime "2026-03-10T10:00:05.250+02:00"^^xsd:dateTime .
ex:naive a prov:Activity ; rdfs:label "naive" ; prov:startedAtTime "2026-03-10T09:00:07"^^xsd:dateTime .
"""


def test_labels_are_found_in_any_case_and_times_drawn_as_the_log_gave_them(memory_api: InProcess) -> None:
    """A search folds a label's case as Python does (ß → ss), whatever SQLite's lower() folds by itself (ASCII
    only); a node's time is drawn in UTC when it had a zone, and as written when it had none; untimed nodes are
    drawn in the order of their IRIs' ends."""
    answer = memory_api.client.post("/ttl", json={"ttl_content": TURTLE, "user": "tester"})
    assert answer.status_code == 201, answer.text

    def found(needle: str) -> set[str]:
        graph = memory_api.get("/graph", params={"q": needle}).json()
        return {node["label"] for node in graph["nodes"] if node["id"] in graph["matches"]}

    assert found("zoë strasse") == {"ZOË STRAßE"}
    assert found("ZOË") == {"ZOË STRAßE"}
    assert found("ana rey") == {"Ana Reyes"}
    assert found("ANA") == {"Ana Reyes"}
    drawn = [
        node for needle in ("zoned", "naive") for node in memory_api.get("/graph", params={"q": needle}).json()["nodes"]
    ]
    times = {node["label"]: node.get("time") for node in drawn}
    assert times == {"zoned": "2026-03-10T08:00:05.25Z", "naive": "2026-03-10T09:00:07"}
    people = memory_api.get("/graph", params={"types": "human"}).json()["nodes"]
    assert [node["label"] for node in people] == ["Ana Reyes", "ZOË STRAßE"]  # untimed: by their IRIs' ends
