"""The findings kept current equal every rule evaluated in full (SPARQL rules by their query, SHACL rules by
pySHACL on every target), after every step of random histories that touch every rule: late links, late times,
late answers, re-publishes and clearings. On the embedded store and on Virtuoso, whole and filtered, paged with
the `next` cursor."""

from __future__ import annotations

import json
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

from segb_server.backend.api.app import create_app
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.rules.catalog import RuleCatalog
from segb_server.backend.services.rules.evaluation import check_store
from segb_server.backend.services.rules.shapes import ShapeRule
from segb_server.backend.store.base import Store
from segb_server.backend.store.oxigraph import OxigraphStore
from tests.conftest import STORE_KINDS, make_settings, virtuoso_store
from tests.support.histories import EX
from tests.support.in_process import InProcess, Server, http
from tests.support.rule_histories import RuleHistory
from tests.support.settle import findings_built, settle

RULES = RuleCatalog(PACKAGE_ROOT / "rules")
# The full evaluation checks the shapes with pySHACL, not with the compiled check the server keeps them by: the
# kept findings are compared with an independent validator.
BY_PYSHACL = {rule.id: ShapeRule(rule, compiled=False) for rule in RULES.shapes()}


def served(server: Server, params: dict[str, str], page: int = 7) -> list[dict[str, object]]:
    findings: list[dict[str, object]] = []
    after: str | None = None
    while True:
        answer = http(
            server, "GET", "/findings", params={**params, "limit": page, **({"after": after} if after else {})}
        )
        assert answer.status_code == 200, answer.text
        body = answer.json()
        findings += body["findings"]
        if not body["has_more"]:
            assert set(body["served_from"].values()) <= {"rows"}, body["served_from"]
            return findings
        after = body["next"]


# Not the rules' own: a line of a checked file, and the focus as the graph draws it (added by GET /findings).
NOT_THE_RULES = ("line", "about")


def canonical(findings: list[dict[str, object]]) -> Counter[str]:
    return Counter(json.dumps({k: v for k, v in f.items() if k not in NOT_THE_RULES}, sort_keys=True) for f in findings)


def in_time_order(findings: list[dict[str, object]]) -> bool:
    from segb_server.backend.services.rules.findings import order_key

    keys = [order_key(f) for f in findings]  # type: ignore[arg-type]
    return keys == sorted(keys)


@pytest.fixture(params=STORE_KINDS)
def server(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[httpx.Client, Store]]:
    if request.param == "virtuoso":
        store: Store = virtuoso_store(request.getfixturevalue("virtuoso"))
    else:
        store = OxigraphStore("http://amor-segb/events", tmp_path / "oxigraph")
    with InProcess(create_app(make_settings(store=request.param, data_dir=tmp_path), store=store)) as served_app:
        findings_built(served_app.client)  # built as the server starts: from then on `settle` tells their lag
        yield served_app.client, store
    if request.param == "virtuoso":
        store.clear()
    store.close()


@pytest.mark.parametrize("seed", [3, pytest.param(7, marks=pytest.mark.slow)])  # a second history: the full tier
def test_findings_equal_every_rule_evaluated_in_full_after_every_step(
    server: tuple[httpx.Client, Store], seed: int
) -> None:
    client, store = server
    history = RuleHistory(seed)
    fired: set[str] = set()
    for step in range(14):
        post = history.next_post()
        if post is None:
            assert client.post("/ttl/delete_all", json={}).status_code == 200
        else:
            answer = client.post("/ttl", content="\n".join(post), headers={"Content-Type": "application/n-triples"})
            assert answer.status_code == 201, answer.text
        settle(client)
        expected = check_store(RULES, store, BY_PYSHACL)
        kept = served(client, {})
        assert canonical(kept) == canonical(expected), (
            step,
            sorted(set(canonical(kept)) ^ set(canonical(expected)))[:4],
        )
        assert in_time_order(kept)
        fired |= {str(f["rule"]) for f in kept}
        if step % 5 == 4:
            robot = f"{EX}robot/ari"
            filtered = served(client, {"robot": robot})
            takes = {rule.id for rule in RULES if rule.kind == "shacl" or "robot" in rule.parameters}
            assert canonical(filtered) == canonical([f for f in expected if f["robot"] == robot and f["rule"] in takes])
            window = {"since": "2026-03-10T09:10:00Z", "until": "2026-03-10T09:30:00Z"}
            timed = served(client, window)
            takes = {rule.id for rule in RULES if rule.kind == "shacl" or "since" in rule.parameters}
            assert canonical(timed) == canonical(
                [
                    f
                    for f in expected
                    if f["rule"] in takes and f["time"] and "09:10:00" <= str(f["time"])[11:19] <= "09:30:00"
                ]
            )
    assert fired == {rule.id for rule in RULES}  # every rule found something along the way, and lost it at a clearing
