"""The findings page in real Chromium: counts by rule and severity, findings in time order with robot, human,
message and an explain link, the violations badge in the navigation, live updates as robots publish, marks on
the explain page and in the conversations, robot text escaped, and a rule added as a file shown with no code
change."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from semantic_log_generator import SEGBPublisher

from segb_server.backend.store.base import Store
from segb_server.examples.emotion_mirror.mission import EmotionMirrorMission, RobotConfig
from tests.api.test_findings import NEW_SPARQL_RULE, SHIPPED
from tests.conftest import UiStack, start_ui_stack
from tests.support.rule_scenarios import troubled
from tests.support.scenarios import at
from tests.support.settle import settle
from tests.ui.conftest import axe_violations

pytestmark = pytest.mark.browser

ARRIVAL_TIMEOUT_MS = 10_000
HOSTILE = '<img src=x onerror="window.__hacked=1">Hello'


def test_the_findings_page_counts_lists_marks_and_follows_what_robots_publish(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    scenario, expected = troubled()
    scenario.publish_all(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/findings")
    counts = {
        row.get_attribute("data-rule"): int(row.locator("td.count").inner_text())
        for row in page.locator("#findings-counts tbody tr").all()
    }
    assert counts == {rule: len(nodes) for rule, nodes in expected.items()}
    assert "3 violations" in page.inner_text("#findings-counts")
    assert page.inner_text("#badge-findings").startswith("3")  # the navigation's open violations
    rows = page.locator("#findings-list tr.finding")
    assert rows.count() == sum(len(nodes) for nodes in expected.values())
    late = page.locator("#findings-list tr.finding", has_text="ARI answered Maria after 14 s")
    assert late.locator("td").nth(3).inner_text() == "ARI" and late.locator("td").nth(4).inner_text() == "Maria"
    assert late.locator("a.explain-link").get_attribute("href").startswith("/explain?iri=")
    assert axe_violations(page) == []

    # A robot publishes a message nobody answers: it appears without navigation, marked new; the text is escaped.
    page.evaluate("window.__sameDocument = true")
    page.wait_for_selector("#live-toggle[aria-pressed='true']")
    publisher = SEGBPublisher(base_url=ui_stack.api_url, default_user="mirror")
    mission = EmotionMirrorMission.start(
        RobotConfig(), human_id="maria", human_name="Maria", publish=lambda logger: logger.publish(publisher)
    )
    heard = mission.on_user_utterance(HOSTILE, at(300)).heard
    arrived = page.locator("#findings-list tr.finding.fresh", has_text=HOSTILE)
    arrived.wait_for(timeout=ARRIVAL_TIMEOUT_MS)
    assert page.evaluate("window.__sameDocument") is True and page.evaluate("window.__hacked") is None

    # The explain page and the conversations mark what a finding is about.
    page.goto(f"{ui_stack.ui_url}/explain?{httpx.QueryParams({'iri': str(heard)})}")
    assert "Message never answered" in page.inner_text(".story")
    page.goto(f"{ui_stack.ui_url}/reports/conversations")
    bubble = page.locator("li.bubble", has_text=HOSTILE)
    assert "Message never answered" in bubble.inner_text()
    assert page.evaluate("window.__hacked") is None
    assert page.console_errors == []


@pytest.fixture
def stack_with_a_new_rule(memory_store: Store, tmp_path: Path) -> Iterator[UiStack]:
    rules = tmp_path / "rules"
    shutil.copytree(SHIPPED, rules)
    (rules / "silent-robot.rq").write_text(NEW_SPARQL_RULE, encoding="utf-8")
    yield from start_ui_stack(memory_store, rules_dir=rules)


def test_a_rule_added_as_a_file_shows_on_the_page(stack_with_a_new_rule: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    nameless = "<https://example.org/robots/r2d2> a <http://kb.openrobots.org#Robot> ."
    answer = httpx.post(
        f"{stack_with_a_new_rule.api_url}/ttl", content=nameless, headers={"Content-Type": "text/turtle"}
    )
    assert answer.status_code == 201
    settle(stack_with_a_new_rule.api_url)
    page.goto(f"{stack_with_a_new_rule.ui_url}/findings?rule=silent-robot")
    assert page.inner_text("#findings-counts tr[data-rule='silent-robot'] td.count") == "1"
    assert "This robot has no name" in page.inner_text("#findings-list")
    assert page.inner_text("#badge-findings").startswith("1")
