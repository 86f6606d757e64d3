"""/reports in real headless Chromium: names, texts, charts, filters, downloads, empty and error states."""

from __future__ import annotations

import httpx
import pytest
from semantic_log_generator import ActivityKind, SEGBPublisher

from tests.conftest import UiStack, make_settings
from tests.support.live_server import LiveServer
from tests.support.net import free_port
from tests.support.scenarios import RESPONSE, at, lobby
from tests.support.settle import settle

pytestmark = pytest.mark.browser

HOSTILE = '<script>window.__pwned = 1</script><img src=x onerror="window.__pwned = 2">'


def publish_lobby_with_hostile_text(api_url: str) -> dict[str, str]:
    scenario = lobby()
    scenario.publish_all(api_url)
    ari = scenario.loggers["ari"]
    reply = ari.log_activity(activity_id="reply_hostile", activity_kind=ActivityKind.RESPONSE, started_at=at(30))
    ari.log_message(
        HOSTILE, message_id="hostile", message_types=[RESPONSE], generated_by_activity=reply,
        previous_message=scenario.iris["maria_2"], sender=ari.robot_uri,
    )  # fmt: skip
    ari.publish(SEGBPublisher(base_url=api_url))
    settle(api_url)  # the page is read once: its rows must include the last post
    return {name: str(iri) for name, iri in scenario.iris.items()}


def test_reports_page_shows_participants_conversations_and_charts(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    publish_lobby_with_hostile_text(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/reports")

    participants = page.locator("#report-participants").inner_text()
    assert "Maria" in participants and "Juan" in participants and "TIAGo" in participants
    threads = page.locator("#report-conversations article.thread")
    assert threads.count() == 2
    ari_maria = threads.filter(has_text="ARI ↔ Maria")
    assert ari_maria.locator(".bubble-human").count() == 2
    assert "Congratulations, Maria!" in ari_maria.locator(".bubble-robot").first.inner_text()
    assert "Where is the pharmacy?" in threads.filter(has_text="TIAGo ↔ Juan").inner_text()
    # one chart per emotion target, one dot per reading, coloured per category
    charts = page.locator("#report-emotion-timeline figure.chart")
    assert charts.count() == 3
    assert page.locator("#report-emotion-timeline svg.emotion-chart circle").count() == 3
    assert charts.filter(has_text="Juan").locator("g.series").get_attribute("data-category") == "anger"
    assert page.locator("#report-ml-usage svg.bar-chart rect").count() == 2
    assert "arm_calibrated" in page.locator("#report-robot-states").inner_text()
    assert page.console_errors == []


def test_robot_text_is_shown_as_text_never_run(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    publish_lobby_with_hostile_text(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/reports")
    bubble = page.locator("#report-conversations .bubble-text", has_text="window.__pwned")
    assert bubble.inner_text() == HOSTILE
    assert page.evaluate("window.__pwned") is None
    assert page.locator("#report-conversations img").count() == 0


def test_filters_and_links_lead_to_one_report_and_its_explanation(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    iris = publish_lobby_with_hostile_text(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/reports")
    page.select_option("select[name=human]", label="Juan")
    page.click("form.filters button[type=submit]")
    page.wait_for_load_state()
    assert "human=" in page.url
    assert page.locator("#report-conversations article.thread").count() == 1
    assert "Maria" not in page.locator("#report-conversations").inner_text()

    page.click("#report-conversations h2 a")
    page.wait_for_load_state()
    assert page.url.startswith(f"{ui_stack.ui_url}/reports/conversations?")
    explain = page.locator(".bubble", has_text="Where is the pharmacy?").locator("a.explain-link")
    assert iris["juan_1"] in httpx.URL(ui_stack.ui_url + explain.get_attribute("href")).params["iri"]
    assert page.console_errors == []


def test_downloads_carry_the_filters(ui_stack: UiStack) -> None:
    iris = publish_lobby_with_hostile_text(ui_stack.api_url)
    answer = httpx.get(f"{ui_stack.ui_url}/reports/conversations/download.csv", params={"robot": iris["tiago"]})
    assert answer.status_code == 200
    assert answer.headers["content-disposition"] == 'attachment; filename="conversations.csv"'
    lines = answer.text.strip().splitlines()
    assert lines[0].startswith("robot,robotName,human") and len(lines) == 3  # header + Juan's two messages
    as_json = httpx.get(f"{ui_stack.ui_url}/reports/participants/download.json").json()
    assert {row["humanName"] for row in as_json["rows"]} == {"Maria", "Juan"}


def test_empty_store_shows_what_is_missing(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    page.goto(f"{ui_stack.ui_url}/reports")
    assert "No conversations yet — robots have not published messages." in page.inner_text("#report-conversations")
    assert page.locator("#content .empty").count() == 6
    assert page.console_errors == []


def test_reports_page_says_when_the_api_is_down(memory_store) -> None:  # type: ignore[no-untyped-def]
    from segb_server.ui.app import create_ui_app

    with LiveServer(create_ui_app(make_settings(backend_url=f"http://127.0.0.1:{free_port()}"))) as ui:
        answer = httpx.get(f"{ui.url}/reports")
    assert answer.status_code == 503
    assert "The SEGB API is unavailable" in answer.text and "does not answer" in answer.text


def test_a_bad_filter_is_explained_on_the_page(ui_stack: UiStack) -> None:
    answer = httpx.get(f"{ui_stack.ui_url}/reports", params={"robot": "ari"})
    assert answer.status_code == 422
    assert "robot" in answer.text and "absolute IRI" in answer.text


def test_a_time_picked_without_zone_is_read_as_utc(ui_stack: UiStack) -> None:
    publish_lobby_with_hostile_text(ui_stack.api_url)
    # What a datetime-local input submits: no zone. The page labels times as UTC.
    answer = httpx.get(f"{ui_stack.ui_url}/reports/emotion-timeline", params={"since": "2026-03-10T09:00:07"})
    assert answer.status_code == 200
    assert "Juan" in answer.text and "Maria" not in answer.text.split('id="report-emotion-timeline"')[1]


def test_words_overheard_from_an_unseen_speaker_are_not_the_robots(demo_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    """TIAGo overheard an utterance without seeing who spoke (the demo logs no sender): the bubble stands on the
    speakers' side, unnamed, never as TIAGo's words."""
    page.goto(f"{demo_stack.ui_url}/reports/conversations")
    said = page.locator(".bubble", has_text="I did not expect to pass on the first try")
    assert [said.nth(i).get_attribute("class") for i in range(said.count())].count("bubble bubble-unidentified") == 1
    overheard = said.and_(page.locator(".bubble-unidentified"))
    assert overheard.locator(".bubble-meta").inner_text().startswith("Unidentified speaker · ")
    assert "TIAGo" not in overheard.locator(".bubble-meta").inner_text()
    heard_from_maria = said.and_(page.locator(".bubble-human")).first  # the same words, sent by Maria

    def indent(bubble) -> float:  # type: ignore[no-untyped-def]  # from the left edge of its own chat
        return bubble.bounding_box()["x"] - bubble.locator("xpath=..").bounding_box()["x"]

    assert indent(overheard) == indent(heard_from_maria) == 0  # on the speakers' side, not the robot's
    assert page.console_errors == []
