"""The CSV downloads (reports, timeline, findings) hold robots' text: a cell a spreadsheet would run as a formula
(`=HYPERLINK(…)` said by a visitor) is written as text, with a leading apostrophe; numbers keep their sign."""

from __future__ import annotations

import csv
import io

import httpx
from semantic_log_generator import SEGBPublisher

from segb_server.backend.services.csv_cells import spreadsheet_safe
from tests.support.live_server import LiveServer
from tests.support.people import conversation
from tests.support.scenarios import robot_logger
from tests.support.settle import settle

SAID = '=HYPERLINK("http://evil.example/","click")'
REPLIED = "@SUM(1+1)*cmd|' /C calc'!A0"


def cells(text: str) -> list[str]:
    return [cell for row in csv.reader(io.StringIO(text)) for cell in row]


def test_robot_text_that_looks_like_a_formula_is_written_as_text(live_api: LiveServer) -> None:
    robot = robot_logger("ari", "ARI")
    visitor = robot.register_human("v1", first_name="+Mallory")
    model = robot.register_ml_model("emotion_cnn", label="-Emotion CNN", version="1.0")
    conversation(robot, "m1", visitor, SAID, REPLIED, 5, model)
    robot.publish(SEGBPublisher(base_url=live_api.url, default_user="ari"))
    settle(live_api.url)
    get = lambda path, **params: httpx.get(f"{live_api.url}{path}", params={**params, "format": "csv"})  # noqa: E731
    downloads = {
        "conversations": get("/reports/conversations").text,
        "participants": get("/reports/participants").text,
        "ml-usage": get("/reports/ml-usage").text,
        "timeline": get("/timeline", robot=str(robot.robot_uri)).text,
        "findings": get("/findings").text,
    }
    written = {name: cells(text) for name, text in downloads.items()}
    assert "'" + SAID in written["conversations"] and "'" + REPLIED in written["conversations"]
    assert any(SAID in cell for cell in written["timeline"])  # quoted inside a sentence there: no formula
    assert "'+Mallory" in written["participants"]
    for name, found in written.items():
        formulas = [cell for cell in found if cell.startswith(("=", "+", "-", "@")) and spreadsheet_safe(cell) != cell]
        assert formulas == [], name


def test_numbers_keep_their_sign_and_plain_text_is_unchanged() -> None:
    assert [spreadsheet_safe(value) for value in ("-0.8", "+3", "1e-3", "-.5", "Hello", "")] == [
        "-0.8", "+3", "1e-3", "-.5", "Hello", "",
    ]  # fmt: skip
    assert [spreadsheet_safe(value) for value in ("=1+1", "-1+1", "@A1", "\t=A1", "+")] == [
        "'=1+1", "'-1+1", "'@A1", "'\t=A1", "'+",
    ]  # fmt: skip
