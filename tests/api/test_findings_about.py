"""Each finding of `GET /findings` carries what it is about as the graph draws it (`about`), so a page names it
without asking for each node."""

from __future__ import annotations

from segb_server.backend.api.app import create_app
from tests.api.test_findings import all_findings
from tests.conftest import make_settings
from tests.support.in_process import InProcess, http
from tests.support.settle import settle


def test_each_finding_carries_its_focus_as_the_graph_draws_it() -> None:
    with InProcess(create_app(make_settings(), demo=True)) as live:
        settle(live.client)
        found = all_findings(live.client)
        drawn = {
            str(finding["focus"]): http(
                live.client, "GET", "/graph", params={"focus": str(finding["focus"]), "depth": "0"}
            ).json()["nodes"]
            for finding in found
        }
    assert len(found) == 6
    about = {str(finding["focus"]): finding["about"] for finding in found}
    assert all([about[focus]] == nodes for focus, nodes in drawn.items())
    kinds = {(finding["rule"], nodes[0]["kind"]) for finding in found for nodes in [drawn[str(finding["focus"])]]}
    assert kinds == {("reply-without-model", "message"), ("strong-negative-emotion", "emotion")}
    (anger,) = [drawn[str(finding["focus"])][0] for finding in found if finding["rule"] == "strong-negative-emotion"]
    assert anger["label"] == "anger 0.88"
