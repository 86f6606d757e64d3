"""A time window that ends before it starts is a 422 naming `until`, on every route that takes one: the reports,
the findings, the graph, the timeline and the evidence bundle (one rule: `catalog.check_window`)."""

from __future__ import annotations

import pytest

from tests.support.in_process import InProcess

SINCE, UNTIL = "2026-03-11T00:00:00Z", "2026-03-10T00:00:00Z"
ROBOT = "https://example.org/robots/ari"


def windowed_routes(api: InProcess) -> list[tuple[str, dict[str, str]]]:
    reports = [
        report["name"]
        for report in api.client.get("/reports").json()["reports"]
        if {"since", "until"} <= {parameter["name"] for parameter in report["parameters"]}
    ]
    assert reports, "no report takes a time window"
    return [
        *((f"/reports/{name}", {}) for name in reports),
        ("/findings", {}),
        ("/graph", {}),
        ("/timeline", {"robot": ROBOT}),
        ("/evidence", {"robot": ROBOT}),
    ]


def test_a_window_ending_before_it_starts_is_refused_naming_until(memory_api: InProcess) -> None:
    for path, params in windowed_routes(memory_api):
        answer = memory_api.client.get(path, params={**params, "since": SINCE, "until": UNTIL})
        assert answer.status_code == 422, (path, answer.text)
        assert "until" in answer.json()["detail"] and "since" in answer.json()["detail"], (path, answer.text)


@pytest.mark.parametrize("until", [SINCE, "2026-03-12T00:00:00+01:00"])
def test_a_window_of_one_instant_or_across_zones_is_accepted(memory_api: InProcess, until: str) -> None:
    for path, params in windowed_routes(memory_api):
        answer = memory_api.client.get(path, params={**params, "since": SINCE, "until": until})
        assert answer.status_code == 200, (path, answer.text)
