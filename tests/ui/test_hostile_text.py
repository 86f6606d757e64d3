"""Robot-supplied text and IRIs that try to become markup or script stay inert on /kg-graph and /explain."""

from __future__ import annotations

import httpx
import pytest
from semantic_log_generator import ActivityKind, SEGBPublisher

from tests.conftest import UiStack
from tests.support.scenarios import INITIAL, RESPONSE, at, robot_logger
from tests.support.settle import settle

pytestmark = pytest.mark.browser

SCRIPT = "<script>window.__pwned = 1</script>"
IMG = '"><img src=x onerror="window.__pwned = 2">'
JAVASCRIPT_IRI = "javascript:window.__pwned=3"


def publish_hostile(api_url: str) -> dict[str, str]:
    robot = robot_logger("evil", IMG)
    human = robot.register_human("eve", first_name=SCRIPT)
    listen = robot.log_activity(activity_id="listen", activity_kind=ActivityKind.LISTENING, started_at=at(1))
    heard = robot.log_message(
        SCRIPT, message_id="heard", language="en", message_types=[INITIAL], generated_by_activity=listen, sender=human
    )
    reply = robot.log_activity(
        activity_id="reply", activity_kind=ActivityKind.RESPONSE, started_at=at(2), triggered_by_entity=heard
    )
    said = robot.log_message(
        IMG, message_id="said", message_types=[RESPONSE], generated_by_activity=reply, sender=robot.robot_uri
    )
    robot.publish(SEGBPublisher(base_url=api_url))
    # An IRI with the javascript: scheme, linked to the reply (the client would refuse it; raw Turtle does not).
    turtle = f"<{said}> <http://www.w3.org/2000/01/rdf-schema#seeAlso> <{JAVASCRIPT_IRI}> ."
    posted = httpx.post(f"{api_url}/ttl", content=turtle, headers={"Content-Type": "text/turtle"})
    assert posted.status_code == 201
    settle(api_url)  # the graph and the reports are read once: they must include both posts
    return {"said": str(said), "human": str(human)}


def assert_inert(page) -> None:  # type: ignore[no-untyped-def]
    assert page.evaluate("window.__pwned") is None
    assert page.locator("#content img").count() == 0
    assert page.locator("#content script").count() == 0
    assert page.locator("a[href^='javascript:']").count() == 0


def test_graph_panel_shows_hostile_labels_and_iris_as_text(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    iris = publish_hostile(ui_stack.api_url)
    dialogs: list[str] = []
    page.on("dialog", lambda dialog: (dialogs.append(dialog.message), dialog.dismiss()))
    page.goto(f"{ui_stack.ui_url}/kg-graph")
    page.wait_for_selector("#graph[data-ready=true]")
    page.fill("#graph-search-input", "message_said")
    page.click("#graph-search button")
    page.wait_for_selector(f"#graph-panel[data-iri='{iris['said']}']")
    panel = page.locator("#graph-panel")
    assert IMG in panel.locator("h2").inner_text()
    link = panel.locator(f"a[title='{JAVASCRIPT_IRI}']")  # the IRI in the tooltip, the link named by its words
    assert link.count() == 1
    link.click()  # a link inside the app, never a navigation to the IRI
    page.wait_for_timeout(300)
    assert page.url.startswith(ui_stack.ui_url)
    assert_inert(page)
    assert dialogs == []


def test_explain_page_tells_hostile_text_as_text(ui_stack: UiStack, page) -> None:  # type: ignore[no-untyped-def]
    iris = publish_hostile(ui_stack.api_url)
    page.goto(f"{ui_stack.ui_url}/explain?" + str(httpx.QueryParams({"iri": iris["said"]})))
    sentences = page.locator(".story-sentence").all_inner_texts()
    assert sentences == [f"{SCRIPT} said “{SCRIPT}” (heard by {IMG})", f"{IMG} said “{IMG}”"]
    assert_inert(page)
    page.goto(f"{ui_stack.ui_url}/reports")
    assert SCRIPT in page.locator("#report-conversations").inner_text()
    assert_inert(page)
    assert page.console_errors == []
