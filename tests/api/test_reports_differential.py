"""Reports kept current equal their queries evaluated in full, after every step of random histories: several
robots posting in the client's shapes, links arriving late (an activity first, its shared event, model or
emotion later), out-of-order times, re-publishes and clearings. Compared on both stores, with and without
filters, and paged with the `next` cursor."""

from __future__ import annotations

import json
import random
import re
from collections import Counter
from pathlib import Path

import pytest
from pyoxigraph import QueryResultsFormat, parse_query_results

from segb_server.backend.api.app import create_app
from segb_server.backend.config import PACKAGE_ROOT
from segb_server.backend.services.sparql.catalog import Catalog
from segb_server.backend.services.values import json_value
from segb_server.backend.store.oxigraph import OxigraphStore
from segb_server.backend.store.terms import bind_values
from tests.conftest import make_settings
from tests.support.histories import EX, HUMANS, ROBOTS, History, iri, send, term, time_literal
from tests.support.in_process import InProcess, Server, http
from tests.support.settle import settle

CATALOG = Catalog(PACKAGE_ROOT / "sparql")
REPORTS = [query for query in CATALOG.under("reports")]


def full_evaluation(server: Server, text: str) -> list[dict[str, object]]:
    answer = http(
        server, "POST", "/sparql", data={"query": text}, headers={"Accept": "application/sparql-results+json"}
    )
    assert answer.status_code == 200, answer.text
    solutions = parse_query_results(answer.content, QueryResultsFormat.JSON)
    names = [variable.value for variable in solutions.variables]  # type: ignore[union-attr]
    return [{name: json_value(solution[name]) for name in names} for solution in solutions]  # type: ignore[union-attr]


def report_rows(server: Server, name: str, params: dict[str, str], page: int) -> list[dict[str, object]]:
    rows: list[dict[str, object]] = []
    after: str | None = None
    while True:
        query = {**params, "limit": page, **({"after": after} if after else {})}
        answer = http(server, "GET", f"/reports/{name}", params=query)
        assert answer.status_code == 200, answer.text
        body = answer.json()
        rows += body["rows"]
        if not body["has_more"]:
            return rows
        after = body["next"]
        assert after, "a page with more rows names the next one"


def same_rows(
    served: list[dict[str, object]], evaluated: list[dict[str, object]], order: list[str], context: str
) -> None:
    """The same rows (as a multiset), and in an order ORDER BY allows (ties may come in any order)."""
    canonical = [json.dumps(row, sort_keys=True) for row in served]
    expected = [json.dumps(row, sort_keys=True) for row in evaluated]
    assert Counter(canonical) == Counter(expected), (context, sorted(set(canonical) ^ set(expected))[:4])
    rank = {}
    for index, row in enumerate(evaluated):
        rank.setdefault(tuple(json.dumps(row.get(column)) for column in order), index)
    ranks = [rank[tuple(json.dumps(row.get(column)) for column in order)] for row in served]
    assert ranks == sorted(ranks), (context, "rows out of ORDER BY order")


def bound_text(name: str, params: dict[str, str]) -> str:
    query = CATALOG.get(name)
    return bind_values(query.text, query.bindings(params))


@pytest.mark.parametrize("seed", [1, pytest.param(2, marks=pytest.mark.slow)])  # a second history: the full tier
def test_reports_equal_their_full_evaluation_after_every_step(store_server: str, seed: int) -> None:
    server = store_server
    history = History(seed)
    speakers: dict[object, set[object]] = {}  # each message's speakers over the steps: late links change them
    for step in range(16):
        send(server, history.next_post())
        settle(server)
        variants = [{}]
        if step % 4 == 3:
            rng = random.Random(seed * 100 + step)
            variants += [
                {"robot": f"{EX}robot/{rng.choice(ROBOTS)}"},
                {"human": f"{EX}human/{rng.choice(HUMANS)}"},
                {"since": "2026-03-10T09:20:00Z", "until": "2026-03-10T09:40:00Z"},
            ]
        conversations = served_equal_evaluated(server, variants, step, page=12)
        for row in conversations:
            speakers.setdefault(row["message"], set()).add(row["speaker"])
    assert set().union(*speakers.values()) == {"human", "robot", "unidentified"}  # the histories reached each


@pytest.mark.slow  # a long history, then every report evaluated in full after each step
def test_reports_of_one_robot_with_a_long_history_equal_their_full_evaluation(store_server: str) -> None:
    """One robot meeting one person for a long time (its node and theirs gain children with every post), then
    late links, re-publishes and a clearing: what a post changes of hubs that old must still be exact."""
    server = store_server
    history = History(11, robots=("ari",), humans=("maria",))
    for _ in range(4):
        send(server, history.backlog(60))  # 240 interactions before the steps compared
    steps = [history.next_post() for _ in range(8)] + [None, history.next_post(), history.next_post()]
    for step, post in enumerate(steps):
        send(server, post)
        settle(server)
        variants = [{}, {"robot": f"{EX}robot/ari"}, {"human": f"{EX}human/maria"}] if step % 3 == 2 else [{}]
        conversations = served_equal_evaluated(server, variants, step, page=50)
        if step == 0:
            assert len(conversations) >= 240  # the long history is there


def test_filtered_pages_of_rows_at_the_same_time_keep_the_whole_order(store_server: str) -> None:
    """A page is chosen by the first values of its rows' order (a message's robot, person and time) and then
    put in the whole order: messages at three instants, each kept in a batch of its own in the reverse of their
    IRIs' order (so the rows' numbers do not follow it), read in pages as small as one row, unfiltered, for a
    robot, a person, a window and both, equal the query's rows and order (ties broken by the IRIs)."""
    base = [f"{iri('robot', 'ari')} {term('rdf:type')} {term('oro:Robot')} ."]
    base += [f"{iri('human', human)} {term('rdf:type')} {term('oro:Human')} ." for human in ("maria", "juan")]
    send(store_server, base)
    for number in reversed(range(15)):
        message, activity = iri("message", f"m{number:02d}"), iri("activity", f"a{number:02d}")
        send(store_server, [
            f"{message} {term('rdf:type')} {term('schema:Message')} .",
            f'{message} {term("schema:text")} "message {number}"@en .',
            f"{message} {term('prov:wasGeneratedBy')} {activity} .",
            f"{message} {term('schema:sender')} {iri('human', ('maria', 'juan')[number % 2])} .",
            f"{activity} {term('segb:wasPerformedBy')} {iri('robot', 'ari')} .",
            f"{activity} {term('prov:startedAtTime')} {time_literal(60 * (number % 3))} .",
        ])  # fmt: skip
        settle(store_server)
    variants = [
        {},
        {"robot": f"{EX}robot/ari"},
        {"human": f"{EX}human/maria"},
        {"since": "2026-03-10T09:01:00Z", "until": "2026-03-10T09:02:00Z"},
        {"human": f"{EX}human/juan", "since": "2026-03-10T09:00:00Z", "until": "2026-03-10T09:01:00Z"},
    ]
    for page in (1, 2, 7):
        served_equal_evaluated(store_server, variants, step=page, page=page)


def served_equal_evaluated(
    server: Server, variants: list[dict[str, str]], step: int, page: int
) -> list[dict[str, object]]:
    """Every report, with each variant's parameters it takes, served from its kept rows (paged by `page`) equals
    its query evaluated in full; returns the conversations report's rows served without parameters."""
    conversations: list[dict[str, object]] = []
    for query in REPORTS:
        name = query.name.removeprefix("reports/")
        order = [column[1:] for column in _order_of(query.text)]
        for params in variants:
            accepted = {key: value for key, value in params.items() if key in query.parameters}
            if params and not accepted:
                continue
            served = report_rows(server, name, accepted, page=page)
            evaluated = full_evaluation(server, bound_text(query.name, accepted))
            same_rows(served, evaluated, order, f"step {step}: {name} {accepted}")
            if name == "conversations" and not accepted:
                conversations = served
    served_from = {http(server, "GET", f"/reports/{query.name[8:]}").json()["served_from"] for query in REPORTS}
    assert served_from == {"rows"}  # compared above: the rows kept current, not an evaluation
    return conversations


def _order_of(text: str) -> list[str]:
    found = re.search(r"ORDER BY\s+(.*)$", text, re.DOTALL)
    return found.group(1).split() if found else []


@pytest.mark.slow  # three servers in turn, every report compared after each post of the last
def test_reports_kept_again_after_posts_taken_without_views_equal_their_full_evaluation(tmp_path: Path) -> None:
    """Posts a server took with its views off are in the store, not in the registry of the IRIs the store holds
    (`views/seen_terms.py`): when the views are kept again, the registry catches up from the journal before any
    later post's joins are followed among its own triples, so a late link to a resource of those posts reaches
    the store's triples about it."""
    store = OxigraphStore("http://amor-segb/events", tmp_path / "oxigraph")
    history = History(11)

    def posted(live: InProcess, count: int) -> None:
        for _ in range(count):
            post = history.next_post()
            if post is not None:
                answer = live.post("/ttl", content="\n".join(post), headers={"Content-Type": "application/n-triples"})
                assert answer.status_code == 201, answer.text

    try:
        for keep_views, count in ((True, 10), (False, 15)):
            settings = make_settings(store="oxigraph", data_dir=tmp_path / "data", keep_views=keep_views)
            with InProcess(create_app(settings, store=store)) as live:
                posted(live, count)
        settings = make_settings(store="oxigraph", data_dir=tmp_path / "data")
        with InProcess(create_app(settings, store=store)) as live:
            for step in range(15):
                posted(live, 1)
                settle(live.client)
                served_equal_evaluated(live.client, [{}, {"human": f"{EX}human/maria"}], step, page=50)
    finally:
        store.close()


def test_reports_built_from_a_store_that_holds_a_history_equal_their_full_evaluation(tmp_path: Path) -> None:
    """A server started on a store that already holds the logs (an import, a lost or outdated rows file)
    builds the rows in one evaluation: every filter then answers as the query does."""
    store = OxigraphStore("http://amor-segb/events", tmp_path / "oxigraph")
    settings = make_settings(store="oxigraph", data_dir=tmp_path / "data")
    history = History(5)
    try:
        with InProcess(create_app(settings, store=store)) as live:
            for _ in range(12):
                post = history.next_post()
                if post is not None:
                    answer = live.post(
                        "/ttl", content="\n".join(post), headers={"Content-Type": "application/n-triples"}
                    )
                    assert answer.status_code == 201, answer.text
        for view in settings.data_dir.glob("reports.sqlite3*"):
            view.unlink()
        with InProcess(create_app(settings, store=store)) as live:
            settle(live.client)
            for query in REPORTS:
                name = query.name.removeprefix("reports/")
                order = [column[1:] for column in _order_of(query.text)]
                variants = [{}, {"robot": f"{EX}robot/ari"}, {"human": f"{EX}human/maria"}]
                for params in variants:
                    accepted = {key: value for key, value in params.items() if key in query.parameters}
                    if params and not accepted:
                        continue
                    evaluated = full_evaluation(live.client, bound_text(query.name, accepted))
                    served = report_rows(live.client, name, accepted, page=50)
                    same_rows(served, evaluated, order, f"{name} {accepted}")
    finally:
        store.close()
